"""The config of `bf16` and `fp16` (their handlers: pilotlab/strategies/half.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class HalfConfig:
    version: int = 1
    allow_emulated: bool = False     # run even where the CPU has no native 16-bit arithmetic


register_strategy("bf16", HalfConfig, "pilotlab.strategies.half:bf16", hardware_dependent=True)
register_strategy("fp16", HalfConfig, "pilotlab.strategies.half:fp16", hardware_dependent=True)
