"""Structured pruning then XNNPACK int8: `structured_prune_litert_int8` — the `structured_prune_int8`
recipe (30 % of the channels removed, kept counts rounded to multiples of 8, fine-tuned) with the
int8 step done by LiteRT (TF Lite's int8 with float input/output), the runtime that runs PilotNet's
int8 fastest here at batch 1 and batch 64 (ExecuTorch's XNNPACK was measured too: slower,
docs/strategies.md).

Why: ONNX Runtime's int8 PilotNet spends a third of its batch-1 time outside the int8 GEMMs
(layout transposes around the fp32 first convolution, quantize/dequantize nodes, the fully
connected layers); XNNPACK keeps NHWC int8 activations from the first layer to the last and
runs the whole network in about a third of ORT's time (docs/strategies.md). Half the MACs on top
of that is what reaches ≥ 10× fp32 eager at batch 1.
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.edge import LITERT_CONVERTER, require
from pilotlab.strategies.common import check_distill, finetune
from pilotlab.strategies.prune import check_fraction
from pilotlab.strategies.registry import StrategySource, register_strategy
from pilotlab.strategies.structured_prune import check_multiple


@dataclass(frozen=True)
class StructuredPruneXnnpackConfig:
    version: int = 1
    amount: float = 0.3              # fraction of each layer's channels / neurons removed
    multiple_of: int = 8             # kept counts rounded to whole 8-wide SIMD blocks
    finetune_epochs: int = 4         # in fp32, before quantization (as structured_prune_int8)
    lr: float = 1e-3
    batch_size: int = 64
    calibration_frames: int = 512
    distill: float = 0.0             # knowledge distillation: weight of the trained baseline's outputs (0-1)

    def __post_init__(self) -> None:
        check_distill(self.distill)
        check_fraction("amount", self.amount)
        check_multiple(self.multiple_of)


def _pruned(config: StructuredPruneXnnpackConfig, source: StrategySource):
    from pilotlab.strategies.channels import multiply_accumulates, remove_channels  # torch
    model = source.load_model()
    macs_before = multiply_accumulates(model, source.input_shape)
    kept = remove_channels(model, config.amount, source.input_shape, config.multiple_of)
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size,
                       distill=config.distill)
    figures = {"kept_channels": kept, "macs": multiply_accumulates(model, source.input_shape),
               "macs_before": macs_before, "finetune": history}
    return model.eval(), figures


def _record_pruning(source: StrategySource, figures: dict) -> None:
    """Add the pruning figures to the artifact.json the int8 step wrote (the benchmark reads macs)."""
    import dataclasses
    from pilotlab.strategies.artifact import read_meta
    meta = read_meta(source.out)
    source.write(dataclasses.replace(meta, extra={**meta.extra, "kept_channels": figures["kept_channels"],
                                                  "macs": figures["macs"]}))


@register_strategy("structured_prune_litert_int8", StructuredPruneXnnpackConfig)
def structured_prune_litert_int8(config: StructuredPruneXnnpackConfig, source: StrategySource) -> dict:
    require(source, LITERT_CONVERTER)
    from pilotlab.strategies.litert_convert import save_tflite
    model, figures = _pruned(config, source)
    result = save_tflite(model, source, "int8", config.calibration_frames)
    _record_pruning(source, figures)
    return {**result, **figures}
