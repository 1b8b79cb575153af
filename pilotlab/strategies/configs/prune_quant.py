"""The config of `prune_quant` (its handler: pilotlab/strategies/prune_quant.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.configs.checks import check_fraction
from pilotlab.strategies.registry import register_strategy


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


register_strategy("prune_quant", PruneQuantConfig, "pilotlab.strategies.prune_quant:prune_quant")
