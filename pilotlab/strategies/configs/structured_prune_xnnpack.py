"""The config of `structured_prune_litert_int8` (its handler: pilotlab/strategies/structured_prune_xnnpack.py)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pilotlab.strategies.configs.checks import check_distill, check_fraction, check_multiple, check_subsample
from pilotlab.strategies.edge import EXTRA, LITERT_CONVERTER
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class StructuredPruneXnnpackConfig:
    version: int = 2                 # 2: criterion, lr 3e-4 (were: the largest by L1 norm, 1e-3)
    amount: float = 0.3              # fraction of each layer's channels / neurons removed
    multiple_of: int = 8             # kept counts rounded to whole 8-wide SIMD blocks
    subsample_stem: int = 0          # the first N convs at twice their stride, each next at its even taps (stem.py)
    criterion: Literal["activation", "l1"] = "activation"   # channels kept: most output on training frames / largest L1
    finetune_epochs: int = 4         # in fp32, before quantization (as structured_prune_int8)
    lr: float = 3e-4                 # as structured_prune's
    batch_size: int = 64
    calibration_frames: int = 512
    distill: float = 0.0             # knowledge distillation: weight of the trained baseline's outputs (0-1)

    def __post_init__(self) -> None:
        check_distill(self.distill)
        check_fraction("amount", self.amount)
        check_multiple(self.multiple_of)
        check_subsample(self.subsample_stem)


register_strategy("structured_prune_litert_int8", StructuredPruneXnnpackConfig,
                  "pilotlab.strategies.structured_prune_xnnpack:structured_prune_litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA, prepared_by="channel_pruning")
