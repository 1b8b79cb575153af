"""The config of `baseline` (its handler: pilotlab/strategies/baseline.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class BaselineConfig:
    version: int = 1


register_strategy("baseline", BaselineConfig, "pilotlab.strategies.baseline:baseline", takes_onnx=True)
