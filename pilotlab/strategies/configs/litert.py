"""The configs of the LiteRT strategies (their handlers: pilotlab/strategies/litert.py). They need
the optional `edge` extra: without it they are "not applicable" and their handlers are never imported."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.edge import EXTRA, LITERT_CONVERTER
from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class LiteRTConfig:
    version: int = 1


@dataclass(frozen=True)
class LiteRTCalibratedConfig:
    version: int = 1
    calibration_frames: int = 512    # the representative dataset: training frames spread evenly


_HANDLERS = "pilotlab.strategies.litert"
register_strategy("litert", LiteRTConfig, f"{_HANDLERS}:litert_fp32", requires=LITERT_CONVERTER, extra=EXTRA)
register_strategy("litert_dynamic_range", LiteRTConfig, f"{_HANDLERS}:litert_dynamic_range",
                  requires=LITERT_CONVERTER, extra=EXTRA)
register_strategy("litert_float16", LiteRTConfig, f"{_HANDLERS}:litert_float16",
                  requires=LITERT_CONVERTER, extra=EXTRA)
register_strategy("litert_int8", LiteRTCalibratedConfig, f"{_HANDLERS}:litert_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA)
register_strategy("litert_full_int8", LiteRTCalibratedConfig, f"{_HANDLERS}:litert_full_int8",
                  requires=LITERT_CONVERTER, extra=EXTRA)
