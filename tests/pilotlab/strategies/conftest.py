"""A randomly initialised PilotNet checkpoint and a small random FrameSet, shared by the tests."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from matrix.kinds import NotApplicable
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.models import build_model, save_checkpoint
from pilotlab.strategies import STRATEGIES, StrategySource, apply_strategy

RANGES = LabelRanges((0.0, 12.0), (-1.5, 1.5))
# Short fine-tuning and calibration: the tests check the mechanics, not the accuracy.
TEST_OPTIONS = {
    "local_prune": {"finetune_epochs": 1, "batch_size": 16},
    "global_prune": {"finetune_epochs": 1, "batch_size": 16},
    "structured_prune": {"finetune_epochs": 1, "batch_size": 16},
    "cluster": {"finetune_epochs": 1, "batch_size": 16},
    "qat": {"finetune_epochs": 1, "batch_size": 16},
    "prune_quant": {"finetune_epochs": 1, "batch_size": 16},
    "bf16": {"allow_emulated": True},
    "fp16": {"allow_emulated": True},
}


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


@pytest.fixture(scope="session")
def artifacts(tmp_path_factory, trained, frames) -> dict[str, tuple[Path, dict | str]]:
    """Every registered strategy applied once: name -> (artifact folder, result or 'n/a: reason')."""
    root = tmp_path_factory.mktemp("artifacts")
    done = {}
    for name in STRATEGIES:
        source = StrategySource(trained / "model.pt", root / name, (frames,))
        try:
            done[name] = (root / name, apply_strategy(name, TEST_OPTIONS.get(name, {}), source))
        except NotApplicable as reason:
            done[name] = (root / name, f"not applicable: {reason}")
    return done
