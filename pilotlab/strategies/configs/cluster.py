"""The config of `cluster` (its handler: pilotlab/strategies/cluster.py)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pilotlab.strategies.configs.checks import check_clusters
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class ClusterConfig:
    version: int = 1
    clusters: int = 16               # shared values per layer (16 = 4-bit indices)
    iterations: int = 30             # k-means (Lloyd) iterations
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    format: Literal["checkpoint", "torchscript", "onnx"] = "checkpoint"

    def __post_init__(self) -> None:
        check_clusters(self.clusters)   # when the recipe is read (it failed the optimize job in the run)


register_strategy("cluster", ClusterConfig, "pilotlab.strategies.cluster:cluster")
