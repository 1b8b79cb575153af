"""The configs of `local_prune` and `global_prune` (their handlers: pilotlab/strategies/prune.py)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pilotlab.strategies.configs.checks import check_fraction
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class LocalPruneConfig:
    version: int = 1
    conv: float = 0.3                # fraction of each conv layer's weights set to zero
    linear: float = 0.5              # fraction of each linear layer's weights set to zero
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    format: Literal["checkpoint", "torchscript", "onnx"] = "checkpoint"   # checkpoint: eager, as the study

    def __post_init__(self) -> None:  # checked when the recipe is read, not when the job runs
        check_fraction("conv", self.conv)
        check_fraction("linear", self.linear)


@dataclass(frozen=True)
class GlobalPruneConfig:
    version: int = 1
    amount: float = 0.3              # fraction of all conv/linear weights set to zero
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    format: Literal["checkpoint", "torchscript", "onnx"] = "checkpoint"

    def __post_init__(self) -> None:
        check_fraction("amount", self.amount)


register_strategy("local_prune", LocalPruneConfig, "pilotlab.strategies.prune:local_prune", prepared_by="l1_pruning")
register_strategy("global_prune", GlobalPruneConfig, "pilotlab.strategies.prune:global_prune")
