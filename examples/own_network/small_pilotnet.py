"""A small driving network of your own: any torch.nn.Module that maps a batch of preprocessed camera
images [N, 3, 66, 200] (RGB in [0, 1]) to [N, 2] (normalised v, w). About 9,000 parameters.

recipes/own_network.yaml names it `network: ../examples/own_network/small_pilotnet.py:SmallPilotNet`
with `options: {width: 8}` (the constructor's keyword arguments)."""
from torch import nn


class SmallPilotNet(nn.Module):
    def __init__(self, width: int = 8):
        super().__init__()
        self.features = nn.Sequential(
            nn.BatchNorm2d(3),
            nn.Conv2d(3, width, 5, stride=2), nn.ReLU(),                  # [N, w, 31, 98]
            nn.Conv2d(width, 2 * width, 5, stride=2), nn.ReLU(),          # [N, 2w, 14, 47]
            nn.Conv2d(2 * width, 2 * width, 5, stride=2), nn.ReLU(),      # [N, 2w, 5, 22]
            nn.AdaptiveAvgPool2d((1, 8)),                                 # where the line is, left to right
        )
        self.head = nn.Sequential(nn.Flatten(), nn.Linear(16 * width, 32), nn.ReLU(), nn.Linear(32, 2))

    def forward(self, images):
        return self.head(self.features(images))
