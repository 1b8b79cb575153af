"""Every model's config and registration: the arch names and options a recipe may use.

Kept apart from the networks (one file each, `network=` names it) so that checking a recipe's
models needs no torch; a network's class is imported when a model is built.
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.errors import PilotlabError
from pilotlab.models.registry import register_model


@register_model("pilotnet", network="pilotlab.models.pilotnet.PilotNet")
@dataclass(frozen=True)
class PilotNetConfig:
    version: int = 1
    height: int = 66
    width: int = 200
    channels: int = 3
    outputs: int = 2
    dropout: float = 0.0


@register_model("pilotnet_stacked", network="pilotlab.models.pilotnet_stacked.PilotNetStacked")
@dataclass(frozen=True)
class PilotNetStackedConfig:
    version: int = 1
    frames: int = 3                  # consecutive frames per input (the train job and brain read this)
    height: int = 66
    width: int = 200
    outputs: int = 2
    dropout: float = 0.0

    def __post_init__(self):
        if self.frames < 1:
            raise PilotlabError(f"pilotnet_stacked frames = {self.frames} must be at least 1")
