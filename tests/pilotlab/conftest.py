"""Shared fixtures: a randomly initialised PilotNet checkpoint (as the train job writes it), small
random FrameSets (as frames jobs write them), a tiny circuit (a 110 m stadium CSV), and every
registered strategy applied once to that checkpoint (the strategy tests and the export's share it), and
the small pipeline recipe run one job at a time (the slow parallel and Dask tests compare with it)."""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import torch

from matrix.kinds import NotApplicable
from matrix.runs import cores
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.models import build_model, save_checkpoint
from pilotlab.strategies import STRATEGIES
from pilotlab.strategies.apply import StrategySource, apply_strategy
from tests.pilotlab.tracks import stadium, write_csv

RANGES = LabelRanges((0.0, 12.0), (-1.5, 1.5))


@pytest.fixture(scope="session")
def pipeline_one_at_a_time(tmp_path_factory):
    """(recipe, store, plan) of tests/pilotlab/test_dask_pipeline.RECIPE run with one job at a time: the
    reference that the runs with several jobs at once and on Dask must match (run once for both)."""
    from matrix import engine
    from matrix.recipe import load_recipe
    from matrix.store import Store
    from pilotlab.domain import DOMAIN
    from tests.pilotlab.test_dask_pipeline import RECIPE
    folder = tmp_path_factory.mktemp("pipeline")
    (folder / "recipe.yaml").write_text(RECIPE)
    recipe, store = load_recipe(folder / "recipe.yaml", DOMAIN), Store(folder / "one")
    plan = engine.make_plan(recipe, DOMAIN, store)
    summary = engine.run_plan(plan, DOMAIN, store, jobs=1)
    assert not summary.failed, summary.outcomes
    return recipe, store, plan


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

# Short fine-tuning and calibration: the tests check the mechanics, not the accuracy.
TEST_OPTIONS = {
    "local_prune": {"finetune_epochs": 1, "batch_size": 16},
    "global_prune": {"finetune_epochs": 1, "batch_size": 16},
    "structured_prune": {"finetune_epochs": 1, "batch_size": 16},
    "structured_prune_int8": {"finetune_epochs": 1, "batch_size": 16, "calibration_frames": 32},
    "structured_prune_litert_int8": {"finetune_epochs": 1, "batch_size": 16, "calibration_frames": 32},
    "cluster": {"finetune_epochs": 1, "batch_size": 16},
    "prune_litert": {"finetune_epochs": 1, "batch_size": 16},
    "prune_litert_int8": {"finetune_epochs": 1, "batch_size": 16, "calibration_frames": 32},
    "qat_litert_int8": {"qat_epochs": 1, "batch_size": 16, "calibration_frames": 32},
    "pqat_litert_int8": {"finetune_epochs": 1, "qat_epochs": 1, "batch_size": 16, "calibration_frames": 32},
    "cqat_litert_int8": {"finetune_epochs": 1, "qat_epochs": 1, "batch_size": 16, "calibration_frames": 32},
    "pcqat_litert_int8": {"finetune_epochs": 1, "cluster_epochs": 1, "qat_epochs": 1, "batch_size": 16,
                          "calibration_frames": 32},
    "qat": {"finetune_epochs": 1, "batch_size": 16},
    "prune_quant": {"finetune_epochs": 1, "batch_size": 16},
    "bf16": {"allow_emulated": True},
    "fp16": {"allow_emulated": True},
}


# Seconds each strategy took in this fixture (one thread, 2026-11-26; a LiteRT one also pays ~12 s of
# TensorFlow's import once per worker): the longest go first, so that the two workers end together.
SECONDS_TO_APPLY = {"prune_quant": 10.1, "qat": 7.2, "qat_litert_int8": 6.1, "pcqat_litert_int8": 6.0,
                    "prune_litert_int8": 5.9, "cqat_litert_int8": 5.3, "pqat_litert_int8": 5.1,
                    "prune_litert": 5.0, "static_quant": 4.3, "litert": 4.2, "litert_int8": 4.2,
                    "structured_prune_litert_int8": 4.0, "litert_full_int8": 4.0, "litert_float16": 3.2,
                    "litert_dynamic_range": 3.1, "cluster": 3.0, "structured_prune_int8": 2.4}


@pytest.fixture(scope="session")
def artifacts(tmp_path_factory, trained, frames) -> dict[str, tuple[Path, dict | str]]:
    """Every registered strategy applied once: name -> (artifact folder, result or 'n/a: reason').
    Two at a time in their own processes (a LiteRT conversion is ~4 s of one core's Python; there are
    a dozen), the longest first: this fixture is the default run's slowest step (~90 s)."""
    root = tmp_path_factory.mktemp("artifacts")
    names = sorted(STRATEGIES, key=lambda name: -SECONDS_TO_APPLY.get(name, 1.0))
    workers = min(2, cores())
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_one_thread) as pool:
        futures = {name: pool.submit(_apply, name, trained, root / name, frames) for name in names}
        return {name: (root / name, futures[name].result()) for name in STRATEGIES}


def _one_thread() -> None:
    import torch
    torch.set_num_threads(1)     # two workers share the cores


def _apply(name: str, trained: Path, out: Path, frames: Path) -> dict | str:
    source = StrategySource(trained / "model.pt", out, (frames,))
    try:
        return apply_strategy(name, TEST_OPTIONS.get(name, {}), source)
    except NotApplicable as reason:
        return f"not applicable: {reason}"
