"""PilotNetStacked: PilotNet whose input is several consecutive frames stacked on the channels.

DeepLearningStudio's "stacked" PilotNet variant: the network sees `frames` consecutive preprocessed
images (oldest first, 3 channels each, docs/CONVENTIONS.md), so it can infer motion (how fast the red
line moves) that one frame does not show. Same layers as PilotNet; only the input BatchNorm and the
first convolution widen to 3 × frames channels (3 frames: 1,599,140 parameters).
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.errors import PilotlabError
from pilotlab.models.pilotnet import PilotNet, PilotNetConfig
from pilotlab.models.registry import register_model


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


@register_model("pilotnet_stacked", PilotNetStackedConfig)
class PilotNetStacked(PilotNet):
    def __init__(self, config: PilotNetStackedConfig):
        super().__init__(PilotNetConfig(height=config.height, width=config.width, channels=3 * config.frames,
                                        outputs=config.outputs, dropout=config.dropout))
        self.config = config
    # forward: images [N, 3 × frames, 66, 200] in [0, 1] -> [N, 2] normalised v, w (PilotNet's)
