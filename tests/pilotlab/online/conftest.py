"""Artifacts for the brains: the shared random PilotNet checkpoint through the `baseline` strategy, and a
two-frame PilotNetStacked with its own label ranges (random weights: the tests check the plumbing).

The stacked artifact is written as the optimize job should write it (input [N, 6, 66, 200]):
`StrategySource.input_shape` reads `config["channels"]`, which PilotNetStacked's config does not have,
so today's strategies would record 3 channels (see test_brains' xfail test)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import torch

from pilotlab.models import build_model, make_config, save_checkpoint
from pilotlab.strategies.apply import StrategySource, apply_strategy
from pilotlab.strategies.artifact import ArtifactMeta, write_meta

PREPROCESS = {"version": 1, "crop_top": 0.5, "crop_bottom": 1.0, "width": 200, "height": 66, "interpolation": "area"}


def baseline_artifact(checkpoint: Path, out: Path) -> Path:
    apply_strategy("baseline", {}, StrategySource(checkpoint, out))
    return out


@pytest.fixture(scope="session")
def pilotnet_artifact(tmp_path_factory, trained) -> Path:
    return baseline_artifact(trained / "model.pt", tmp_path_factory.mktemp("pilotnet_baseline"))


@pytest.fixture(scope="session")
def stacked_artifact(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("stacked")
    torch.manual_seed(1)
    config = make_config("pilotnet_stacked", {"frames": 2})
    labels, preprocess = {"v": [2.0, 10.0], "w": [-2.0, 2.0]}, {**PREPROCESS, "frames": 2}
    save_checkpoint(folder / "model.pt", build_model("pilotnet_stacked", config), "pilotnet_stacked", config,
                    labels=labels, preprocess=preprocess)
    write_meta(folder, ArtifactMeta(strategy="baseline", strategy_version=1, format="pilotlab-checkpoint",
                                    file="model.pt", runtime="torch", dtype="float32", input_shape=(None, 6, 66, 200),
                                    arch="pilotnet_stacked", config=dataclasses.asdict(config), labels=labels,
                                    preprocess=preprocess))
    return folder
