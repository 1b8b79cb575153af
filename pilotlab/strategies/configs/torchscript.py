"""The config of `torchscript` (its handler: pilotlab/strategies/torchscript.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class TorchScriptConfig:
    version: int = 1


register_strategy("torchscript", TorchScriptConfig, "pilotlab.strategies.torchscript:torchscript")
