"""Shared fixtures: a randomly initialised PilotNet checkpoint (as the train job writes it), small
random FrameSets (as frames jobs write them), and a tiny circuit (a 110 m stadium CSV)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.models import build_model, save_checkpoint
from tests.pilotlab.tracks import stadium, write_csv

RANGES = LabelRanges((0.0, 12.0), (-1.5, 1.5))


def random_frames(count: int, seed: int) -> FrameSet:
    rng = np.random.default_rng(seed)
    labels = np.c_[rng.uniform(0, 12, count), rng.uniform(-1.5, 1.5, count)].astype(np.float32)
    return FrameSet(rng.integers(0, 256, (count, 66, 200, 3), dtype=np.uint8), labels,
                    np.repeat(np.arange(2), count // 2).astype(np.int32), {"source": "random"})


@pytest.fixture(scope="session")
def trained(tmp_path_factory) -> Path:
    """A checkpoint as the train job writes it (random weights)."""
    folder = tmp_path_factory.mktemp("train")
    torch.manual_seed(0)
    model = build_model("pilotnet")
    save_checkpoint(folder / "model.pt", model, "pilotnet", model.config, labels=RANGES.as_dict(),
                    preprocess={"crop_top": 0.5, "size": [200, 66]})
    return folder


@pytest.fixture(scope="session")
def frames(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("frames")
    random_frames(48, seed=1).save(folder)
    return folder


@pytest.fixture(scope="session")
def test_frames(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("test_frames")
    random_frames(24, seed=2).save(folder)
    return folder


@pytest.fixture
def stadium_csv(tmp_path) -> str:
    """A 110 m clockwise stadium (two 30 m straights, 8 m radius bends) as a user circuit CSV."""
    return str(write_csv(tmp_path / "stadium.csv", stadium()))
