"""Networks a user brings, as source text written into a test's folder.

DLS_PILOTNET is an independent copy of DeepLearningStudio's PyTorch PilotNet
(Formula1-FollowLine/pytorch/PilotNet/utils/pilotnet.py), written from its published layer list
(ln_1, cn_1..cn_5, fc_1..fc_5, the ReLUs between), not imported from pilotlab."""
from __future__ import annotations

import sys
from pathlib import Path

DLS_PILOTNET = '''
import torch.nn as nn


class PilotNet(nn.Module):
    def __init__(self, image_shape, num_labels):
        super().__init__()
        self.img_height, self.img_width, self.num_channels = image_shape
        self.ln_1 = nn.BatchNorm2d(self.num_channels, eps=1e-03)
        self.cn_1 = nn.Conv2d(self.num_channels, 24, kernel_size=5, stride=2)
        self.relu1 = nn.ReLU()
        self.cn_2 = nn.Conv2d(24, 36, kernel_size=5, stride=2)
        self.relu2 = nn.ReLU()
        self.cn_3 = nn.Conv2d(36, 48, kernel_size=5, stride=2)
        self.relu3 = nn.ReLU()
        self.cn_4 = nn.Conv2d(48, 64, kernel_size=3, stride=1)
        self.relu4 = nn.ReLU()
        self.cn_5 = nn.Conv2d(64, 64, kernel_size=3, stride=1)
        self.relu5 = nn.ReLU()
        self.flatten = nn.Flatten()
        self.fc_1 = nn.Linear(1 * 18 * 64, 1164)
        self.relu_fc1 = nn.ReLU()
        self.fc_2 = nn.Linear(1164, 100)
        self.relu_fc2 = nn.ReLU()
        self.fc_3 = nn.Linear(100, 50)
        self.relu_fc3 = nn.ReLU()
        self.fc_4 = nn.Linear(50, 10)
        self.relu_fc4 = nn.ReLU()
        self.fc_5 = nn.Linear(10, num_labels)

    def forward(self, img):
        out = self.relu1(self.cn_1(self.ln_1(img)))
        out = self.relu2(self.cn_2(out))
        out = self.relu3(self.cn_3(out))
        out = self.relu4(self.cn_4(out))
        out = self.flatten(self.relu5(self.cn_5(out)))
        out = self.relu_fc1(self.fc_1(out))
        out = self.relu_fc2(self.fc_2(out))
        out = self.relu_fc3(self.fc_3(out))
        out = self.relu_fc4(self.fc_4(out))
        return self.fc_5(out)
'''

DLS_OPTIONS = {"image_shape": [200, 66, 3], "num_labels": 2}


def write(folder: Path, name: str, text: str) -> Path:
    path = Path(folder) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def load_class(path: Path, name: str):
    """The class, imported from the file as the user's own script would (not through pilotlab)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(f"test_user_{path.stem}_{abs(hash(str(path)))}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return getattr(module, name)
