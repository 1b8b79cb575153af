"""Fixtures for BM worlds: the test-written world (always), and BehaviorMetrics' own files where present."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.pilotlab.worlds.synthetic import write_world

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(autouse=True, scope="session")
def world_cache(tmp_path_factory):
    """A cache of converted worlds for this test session, not the user's ~/.cache."""
    saved = os.environ.get("PILOTLAB_CACHE")
    os.environ["PILOTLAB_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if saved is None:
        os.environ.pop("PILOTLAB_CACHE", None)
    else:
        os.environ["PILOTLAB_CACHE"] = saved


@pytest.fixture(scope="session")
def oval_assets(tmp_path_factory) -> Path:
    return write_world(tmp_path_factory.mktemp("assets"))


@pytest.fixture(scope="session")
def bm_assets() -> Path:
    """BehaviorMetrics' worlds: $PILOTLAB_BM_ASSETS, else ../shared/data/bm_worlds beside the repository."""
    for candidate in (os.environ.get("PILOTLAB_BM_ASSETS"), REPO.parent / "shared" / "data" / "bm_worlds"):
        if candidate and (Path(candidate) / "worlds" / "simple_circuit.world").is_file():
            return Path(candidate)
    pytest.skip("BehaviorMetrics' worlds are not here (set PILOTLAB_BM_ASSETS or put them in ../shared/data/bm_worlds)")
