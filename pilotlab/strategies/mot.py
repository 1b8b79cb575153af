"""The 2022 study's TensorFlow Model Optimization rows, built on the torch side and run on LiteRT
(the converter path of litert.py), as the study ran them on TF Lite:

| strategy | the study's row | what it keeps in the artifact |
| --- | --- | --- |
| `prune_litert` | "Weight pruning" | `sparsity` of every conv/dense layer's weights exactly zero (fp32) |
| `prune_litert_int8` | "Weight pruning + Q" | the same zeros, through int8 (symmetric weights map 0 to 0) |
| `qat_litert_int8` | "Q aware training" | weights on the converter's own int8 grid, so conversion does not move them |

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

Every strategy starts from the trained network with its input batch-norm folded into the first
conv (as the export does), so the weights pruned are the weights that reach the artifact.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from pilotlab.strategies.common import finetune
from pilotlab.strategies.edge import LITERT_CONVERTER, require
from pilotlab.strategies.prune import check_fraction
from pilotlab.strategies.registry import StrategySource, register_strategy


@dataclass(frozen=True)
class PruneLiteRTConfig:
    version: int = 1
    sparsity: float = 0.5            # fraction of each conv/linear layer's weights set to zero
    finetune_epochs: int = 2         # fine-tuning with the mask held
    lr: float = 1e-4
    batch_size: int = 64

    def __post_init__(self) -> None:
        check_fraction("sparsity", self.sparsity)


@dataclass(frozen=True)
class QatLiteRTConfig:
    version: int = 1
    qat_epochs: int = 2              # fine-tuning with fake quantization
    lr: float = 1e-4
    batch_size: int = 64
    calibration_frames: int = 512    # ranges observed before QAT; the conversion's representative dataset


@dataclass(frozen=True)
class PruneLiteRTInt8Config(PruneLiteRTConfig):
    calibration_frames: int = 512    # the representative dataset of the int8 conversion


def pruned(config: PruneLiteRTConfig, source: StrategySource):
    """The folded network with its smallest weights masked and fine-tuned; the masks stay on
    (parametrizations) so that a later step (QAT) keeps the zeros too."""
    from pilotlab.strategies.mot_torch import add_masks, fold, magnitude_masks
    model = fold(source.load_model())
    add_masks(model, magnitude_masks(model, config.sparsity))
    history = tune(model, source, config, config.finetune_epochs)
    return model, history


def quantization_aware(model, source: StrategySource, config, history: list[dict]) -> dict:
    """Fake-quantize (on top of any mask or clusters already on the weights), observe the ranges,
    fine-tune, bake and convert to LiteRT int8."""
    from pilotlab.strategies.mot_torch import add_fake_quant, calibrate, remove_hooks
    quant = add_fake_quant(model)
    calibrate(model, quant, source.calibration_batches(config.calibration_frames))
    history = history + tune(model, source, config, config.qat_epochs)
    remove_hooks(quant)
    return save(model, source, "int8", config.calibration_frames, history)


def tune(model, source: StrategySource, config, epochs: int) -> list[dict]:
    return finetune(model, source, epochs=epochs, lr=config.lr, batch_size=config.batch_size)


def save(model, source: StrategySource, mode: str, calibration_frames: int, history: list[dict]) -> dict:
    """Bake the constraints in, convert with LiteRT, record what the weights keep."""
    from pilotlab.strategies.litert_convert import save_tflite
    from pilotlab.strategies.mot_torch import bake, weight_figures
    figures = weight_figures(bake(model))
    result = save_tflite(model, source, mode, calibration_frames)
    _record(source, {"sparsity": figures["sparsity"]})
    return {**result, **figures, "finetune": history}


def _record(source: StrategySource, extra: dict) -> None:
    from pilotlab.strategies.artifact import read_meta
    meta = read_meta(source.out)
    source.write(dataclasses.replace(meta, extra={**meta.extra, **extra}))


@register_strategy("prune_litert", PruneLiteRTConfig)
def prune_litert(config: PruneLiteRTConfig, source: StrategySource) -> dict:
    require(source, LITERT_CONVERTER)
    model, history = pruned(config, source)
    return save(model, source, "float32", 0, history)


@register_strategy("prune_litert_int8", PruneLiteRTInt8Config)
def prune_litert_int8(config: PruneLiteRTInt8Config, source: StrategySource) -> dict:
    require(source, LITERT_CONVERTER)
    model, history = pruned(config, source)
    return save(model, source, "int8", config.calibration_frames, history)


@register_strategy("qat_litert_int8", QatLiteRTConfig)
def qat_litert_int8(config: QatLiteRTConfig, source: StrategySource) -> dict:
    require(source, LITERT_CONVERTER)
    from pilotlab.strategies.mot_torch import fold
    return quantization_aware(fold(source.load_model()), source, config, [])
