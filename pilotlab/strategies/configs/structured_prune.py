"""The config of `structured_prune` (its handler: pilotlab/strategies/structured_prune.py)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pilotlab.strategies.configs.checks import check_distill, check_fraction, check_multiple, check_subsample
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class StructuredPruneConfig:
    version: int = 4                 # 2: kept counts to multiples of 8; 3: 4 epochs at 1e-3; 4: criterion, 3e-4
    amount: float = 0.3              # fraction of each layer's channels / neurons removed
    finetune_epochs: int = 4         # a third of the channels gone is a new network: it needs real training
    lr: float = 3e-4                 # ranked by activation it starts near the trained net; 1e-3 threw it off
    batch_size: int = 64
    format: Literal["torchscript", "onnx"] = "torchscript"   # the shapes change: no checkpoint
    multiple_of: int = 8             # round kept counts to a multiple of this: whole SIMD blocks (1: exact)
    subsample_stem: int = 0          # the first N convs at twice their stride, each next at its even taps (stem.py)
    criterion: Literal["activation", "l1"] = "activation"   # channels kept: most output on training frames / largest L1
    distill: float = 0.0             # knowledge distillation: weight of the trained baseline's outputs (0-1)

    def __post_init__(self) -> None:
        check_distill(self.distill)
        check_fraction("amount", self.amount)
        check_multiple(self.multiple_of)
        check_subsample(self.subsample_stem)


register_strategy("structured_prune", StructuredPruneConfig, "pilotlab.strategies.structured_prune:structured_prune",
                  prepared_by="channel_pruning")
