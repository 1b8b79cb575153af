"""`prune_quant`: the study's best PyTorch model — L1 pruning (per layer, fine-tuned) followed by
quantization-aware fine-tuning that keeps the pruned weights at zero, then int8 (see pt2e.py for
why torchao PT2E -> ONNX QDQ -> ONNX Runtime). Symmetric int8 weights map 0.0 to 0 exactly, so the
sparsity survives quantization.
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.common import sparsity_report
from pilotlab.strategies.prune import check_fraction, prune_and_finetune, prune_local
from pilotlab.strategies.pt2e import quantization_aware_finetune
from pilotlab.strategies.registry import StrategySource, register_strategy


@dataclass(frozen=True)
class PruneQuantConfig:
    version: int = 1
    conv: float = 0.3
    linear: float = 0.5
    calibration_frames: int = 256    # observed before quantization-aware fine-tuning
    finetune_epochs: int = 2         # after pruning, and again with fake quantization
    lr: float = 1e-4
    batch_size: int = 64

    def __post_init__(self) -> None:
        check_fraction("conv", self.conv)
        check_fraction("linear", self.linear)


@register_strategy("prune_quant", PruneQuantConfig)
def prune_quant(config: PruneQuantConfig, source: StrategySource) -> dict:
    model = source.load_model()
    prune_history = prune_and_finetune(model, source, config,
                                       lambda m: prune_local(m, config.conv, config.linear))
    pruned = sparsity_report(model)
    qat_history = quantization_aware_finetune(model, source, config, keep_zeros=True)
    return {**pruned, "finetune": prune_history + qat_history}
