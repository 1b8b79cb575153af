"""PilotNetStacked: PilotNet whose input is several consecutive frames stacked on the channels.

DeepLearningStudio's "stacked" PilotNet variant: the network sees `frames` consecutive preprocessed
images (oldest first, 3 channels each, docs/CONVENTIONS.md), so it can infer motion (how fast the red
line moves) that one frame does not show. Same layers as PilotNet; only the input BatchNorm and the
first convolution widen to 3 × frames channels (3 frames: 1,599,140 parameters). Its config,
`PilotNetStackedConfig` (frames, height, width, outputs, dropout), is in configs.py.
"""
from __future__ import annotations

from pilotlab.models.configs import PilotNetConfig, PilotNetStackedConfig
from pilotlab.models.pilotnet import PilotNet


class PilotNetStacked(PilotNet):
    def __init__(self, config: PilotNetStackedConfig):
        super().__init__(PilotNetConfig(height=config.height, width=config.width, channels=3 * config.frames,
                                        outputs=config.outputs, dropout=config.dropout))
        self.config = config
    # forward: images [N, 3 × frames, 66, 200] in [0, 1] -> [N, 2] normalised v, w (PilotNet's)
