"""The 2022 study's TensorFlow Model Optimization rows, built on the torch side and run on LiteRT
(the converter path of litert.py), as the study ran them on TF Lite:

| strategy | the study's row | what it keeps in the artifact |
| --- | --- | --- |
| `prune_litert` | "Weight pruning" | `sparsity` of every conv/dense layer's weights exactly zero (fp32) |
| `prune_litert_int8` | "Weight pruning + Q" | the same zeros, through int8 (symmetric weights map 0 to 0) |
| `qat_litert_int8` | "Q aware training" | weights on the converter's own int8 grid, so conversion does not move them |
| `pqat_litert_int8` | "PQAT" | pruning, then QAT with the mask held: the zeros stay zero through QAT and int8 |
| `cqat_litert_int8` | "CQAT" | `clusters` shared values per layer, then QAT on the centroids: ≤ `clusters` int8 values per channel |
| `pcqat_litert_int8` | "PCQAT" | pruning, sparsity-preserving clustering (zero is one of the `clusters`), then QAT: both |

Magnitude pruning is TF-MOT's `prune_low_magnitude` at a constant sparsity: in each conv and
linear layer the smallest weights are masked, the network is fine-tuned with the mask held (masked
weights stay zero and get no gradient), and the zeros are baked in. The network keeps its shape, so
the raw size does not change and the runtime's dense kernels run no faster: what pruning buys shows
in the gzip-compressed size (`size_gz_mb`), as TF-MOT shows it.

Quantization-aware training (QAT) fine-tunes with int8 fake quantization on the torch side
(mot_torch.py: weights symmetric per output channel, as the LiteRT converter quantizes them;
activations per tensor after each ReLU, observed on calibration frames first), then bakes the
weights onto the int8 grid and converts as `litert_int8` does (representative dataset, int8 with
float input/output).

Clustering (TF-MOT's `cluster_weights`, linear centroid initialisation) gives each layer `clusters`
trainable shared values (k-means on its weights); fine-tuning trains the centroids, so the weights
stay on them, and QAT then fake-quantizes the clustered weights. Per-channel int8 maps a layer's
centroids to at most `clusters` int8 values in each output channel (each channel has its own scale).

Every fine-tune here (pruning, clustering, QAT) can distill the trained baseline (`distill`: the
weight of its outputs as soft targets beside the labels; common.finetune).

Every strategy starts from the trained network with its input batch-norm folded into the first
conv (as the export does), so the weights pruned are the weights that reach the artifact.

Configs: configs/mot.py, which registers these strategies as needing the `edge` extra, so this
module (TensorFlow through litert_convert) is imported only where it is installed.
"""
from __future__ import annotations

import dataclasses

from torch import nn

from pilotlab.strategies.artifact import read_meta
from pilotlab.strategies.common import finetune
from pilotlab.strategies.configs.mot import (CqatConfig, PcqatConfig, PqatConfig, PruneLiteRTConfig,
                                             PruneLiteRTInt8Config, QatLiteRTConfig)
from pilotlab.strategies.litert_convert import save_tflite
from pilotlab.strategies.mot_torch import (add_clusters, add_fake_quant, bake, calibrate, fold, remove_hooks,
                                           weight_figures)
from pilotlab.strategies.prepared import prepared_network
from pilotlab.strategies.apply import StrategySource


def pruned(config: PruneLiteRTConfig, source: StrategySource) -> tuple[nn.Module, list[dict]]:
    """The folded network with its smallest weights masked and fine-tuned (the magnitude_pruning
    preparation, shared by the strategies that start from it); the masks stay on (parametrizations) so
    that a later step (QAT) keeps the zeros too."""
    model, figures = prepared_network(config, source)
    return model, figures["finetune"]


def quantization_aware(model: nn.Module, source: StrategySource, config, history: list[dict]) -> dict:
    """Fake-quantize (on top of any mask or clusters already on the weights), observe the ranges,
    fine-tune, bake and convert to LiteRT int8."""
    quant = add_fake_quant(model)
    calibrate(model, quant, source.calibration_batches(config.calibration_frames))
    history = history + tune(model, source, config, config.qat_epochs, fake_quant=True)
    remove_hooks(quant)
    return save(model, source, "int8", config.calibration_frames, history)


def tune(model: nn.Module, source: StrategySource, config, epochs: int, fake_quant: bool = False) -> list[dict]:
    return finetune(model, source, epochs=epochs, lr=config.lr, batch_size=config.batch_size,
                    distill=config.distill, fake_quant=fake_quant)


def save(model: nn.Module, source: StrategySource, mode: str, calibration_frames: int, history: list[dict]) -> dict:
    """Bake the constraints in, convert with LiteRT, record what the weights keep."""
    figures = weight_figures(bake(model))
    result = save_tflite(model, source, mode, calibration_frames)
    _record(source, {"sparsity": figures["sparsity"]})
    return {**result, **figures, "finetune": history}


def _record(source: StrategySource, extra: dict) -> None:
    meta = read_meta(source.out)
    source.write(dataclasses.replace(meta, extra={**meta.extra, **extra}))


def prune_litert(config: PruneLiteRTConfig, source: StrategySource) -> dict:
    model, history = pruned(config, source)
    return save(model, source, "float32", 0, history)


def prune_litert_int8(config: PruneLiteRTInt8Config, source: StrategySource) -> dict:
    model, history = pruned(config, source)
    return save(model, source, "int8", config.calibration_frames, history)


def qat_litert_int8(config: QatLiteRTConfig, source: StrategySource) -> dict:
    return quantization_aware(fold(source.load_model()), source, config, [])


def pqat_litert_int8(config: PqatConfig, source: StrategySource) -> dict:
    model, history = pruned(config, source)
    return quantization_aware(model, source, config, history)


def cqat_litert_int8(config: CqatConfig, source: StrategySource) -> dict:
    model = fold(source.load_model())
    add_clusters(model, config.clusters, config.iterations)
    history = tune(model, source, config, config.finetune_epochs)
    return quantization_aware(model, source, config, history)


def pcqat_litert_int8(config: PcqatConfig, source: StrategySource) -> dict:
    model, history = pruned(config, source)
    add_clusters(bake(model), config.clusters, config.iterations, keep_zeros=True)
    history += tune(model, source, config, config.cluster_epochs)
    return quantization_aware(model, source, config, history)
