"""Every registered strategy applied once to the shared random checkpoint."""
from __future__ import annotations

from pathlib import Path

import pytest

from matrix.kinds import NotApplicable
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
