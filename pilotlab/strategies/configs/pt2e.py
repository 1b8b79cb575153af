"""The configs of `static_quant` and `qat` (their handlers: pilotlab/strategies/pt2e.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class StaticQuantConfig:
    version: int = 1
    calibration_frames: int = 512


@dataclass(frozen=True)
class QatConfig:
    version: int = 1
    calibration_frames: int = 256    # observed before fine-tuning, so ranges start calibrated
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64


register_strategy("static_quant", StaticQuantConfig, "pilotlab.strategies.pt2e:static_quant")
register_strategy("qat", QatConfig, "pilotlab.strategies.pt2e:qat")
