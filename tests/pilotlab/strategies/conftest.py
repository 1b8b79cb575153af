"""Every registered strategy applied once to the shared random checkpoint."""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest

from matrix.kinds import NotApplicable
from matrix.runs import cores
from pilotlab.strategies import STRATEGIES
from pilotlab.strategies.apply import StrategySource, apply_strategy

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


@pytest.fixture(scope="session")
def artifacts(tmp_path_factory, trained, frames) -> dict[str, tuple[Path, dict | str]]:
    """Every registered strategy applied once: name -> (artifact folder, result or 'n/a: reason').
    Two at a time in their own processes (a TF Lite conversion is ~10 s of one core's Python; there are
    a dozen), the longest first: this fixture was the default run's slowest step (~200 s alone)."""
    root = tmp_path_factory.mktemp("artifacts")
    names = sorted(STRATEGIES, key=lambda name: ("litert" not in name, name))
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
