"""The config of `tensorrt` (its handler: pilotlab/strategies/cuda.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class TensorRTConfig:
    version: int = 1
    fp16: bool = True


register_strategy("tensorrt", TensorRTConfig, "pilotlab.strategies.cuda:tensorrt", hardware_dependent=True)
