"""PilotNet, as DeepLearningStudio's PyTorch version (Bojarski et al. 2016, NVIDIA).

BatchNorm on the input; convs 24, 36, 48 (5×5, stride 2) and 64, 64 (3×3); FC 1164, 100, 50, 10, 2;
ReLU after every layer but the last. 1,595,528 parameters, 1.34 M of them in the first fully
connected layer; the input BatchNorm's 6 are not trained (the first convolution absorbs them).
Weights start with He (Kaiming) initialisation and biases at zero: with torch's default the
activations shrink layer by layer until the biases decide the 10-unit layer's sign, and for some
seeds all ten units start dead (the network then outputs a constant, whatever it is shown).
DeepLearningStudio's PyTorch PilotNet has no dropout, so `dropout` defaults to 0
(no Dropout module at all); set it to add one after the last convolution. Its config,
`PilotNetConfig` (height, width, channels, outputs, dropout), is in configs.py.
"""
from __future__ import annotations

import torch
from torch import nn

from pilotlab.models.configs import PilotNetConfig


def _conv_out(size: int, kernel: int, stride: int) -> int:
    return (size - kernel) // stride + 1


class PilotNet(nn.Module):
    def __init__(self, config: PilotNetConfig):
        super().__init__()
        self.config = config
        self.input_norm = nn.BatchNorm2d(config.channels, eps=1e-3)
        # Its scale and shift stay as they are (1 and 0, or a loaded network's) while training: the first
        # convolution, without padding, absorbs any per-channel scale and shift exactly, so they add nothing
        # the network can learn, and their gradient is the first convolution's whole input gradient, about
        # a quarter of a training step (batch 64, one core: 322 -> 236 ms on the AMD EPYC host). Its
        # running mean and variance still follow the data.
        self.input_norm.weight.requires_grad_(False)
        self.input_norm.bias.requires_grad_(False)
        self.features = nn.Sequential(
            nn.Conv2d(config.channels, 24, 5, stride=2), nn.ReLU(),  # [N, 24, 31, 98]
            nn.Conv2d(24, 36, 5, stride=2), nn.ReLU(),                # [N, 36, 14, 47]
            nn.Conv2d(36, 48, 5, stride=2), nn.ReLU(),                # [N, 48, 5, 22]
            nn.Conv2d(48, 64, 3), nn.ReLU(),                          # [N, 64, 3, 20]
            nn.Conv2d(64, 64, 3), nn.ReLU(),                          # [N, 64, 1, 18]
            *([nn.Dropout(config.dropout)] if config.dropout else []),
        )
        height, width = config.height, config.width
        for kernel, stride in ((5, 2), (5, 2), (5, 2), (3, 1), (3, 1)):
            height, width = _conv_out(height, kernel, stride), _conv_out(width, kernel, stride)
        self.head = nn.Sequential(
            nn.Flatten(),                                  # [N, 1152]
            nn.Linear(64 * height * width, 1164), nn.ReLU(),
            nn.Linear(1164, 100), nn.ReLU(),
            nn.Linear(100, 50), nn.ReLU(),
            nn.Linear(50, 10), nn.ReLU(),
            nn.Linear(10, config.outputs),                 # [N, 2]: normalised v, w
        )
        self._init_weights()

    def _init_weights(self) -> None:
        layers = [m for m in self.modules() if isinstance(m, (nn.Conv2d, nn.Linear))]
        for layer in layers[:-1]:  # followed by a ReLU
            nn.init.kaiming_normal_(layer.weight, nonlinearity="relu")
            nn.init.zeros_(layer.bias)
        nn.init.zeros_(layers[-1].bias)

    def forward(self, images: torch.Tensor) -> torch.Tensor:  # images: [N, C, 66, 200] in [0, 1]
        return self.head(self.features(self.input_norm(images)))
