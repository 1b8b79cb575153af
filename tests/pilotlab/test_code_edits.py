"""The planner's job keys follow the code: editing a module reruns exactly the jobs built on it.

Each case edits a copy of the source tree and plans the same recipe with it in a fresh interpreter,
so the code fingerprints are read from the edited files, as in a user's checkout.
"""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.child import python_path

ROOT = Path(__file__).resolve().parents[2]
RECIPE = """
name: edits
datasets:
  train: {record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 0.2}}
  test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 2}}
models:
  pilotnet: {arch: pilotnet, epochs: 1}
  stacked: {arch: pilotnet_stacked, options: {frames: 2}, epochs: 1}
matrix:
  model: [pilotnet, stacked]
  strategy: [baseline, local_prune, prune_quant, cluster, dynamic_quant]
  hardware: [cpu]
  circuit: [simple_circuit]
"""


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    """A copy of matrix/ and pilotlab/ to edit, and the recipe beside them."""
    root = tmp_path_factory.mktemp("tree")
    for package in ("matrix", "pilotlab"):
        shutil.copytree(ROOT / package, root / package, ignore=shutil.ignore_patterns("__pycache__"))
    (root / "edits.yaml").write_text(RECIPE)
    return root


def plan_keys(root: Path) -> dict[str, str]:
    """Job name -> key, planned with the code under `root`."""
    process = subprocess.run([sys.executable, "-m", "pilotlab", "plan", "edits.yaml", "--json", "--store", "store"],
                             cwd=root, env={"PYTHONPATH": python_path(root), "PATH": "/usr/bin:/bin"},
                             capture_output=True, text=True, timeout=120)
    assert process.returncode == 0, process.stderr
    return {job["name"]: job["key"] for job in json.loads(process.stdout)}


@pytest.fixture(scope="module")
def original(tree) -> dict[str, str]:
    return plan_keys(tree)


def changed_by_editing(tree: Path, module: str, original: dict[str, str], edit: str = "\n_EDITED = 1\n") -> set[str]:
    path = tree / module
    text = path.read_text()
    path.write_text(text + edit)
    try:
        keys = plan_keys(tree)
    finally:
        path.write_text(text)
    assert keys.keys() == original.keys()
    return {name for name in keys if keys[name] != original[name]}


def jobs_of_model(model: str, original: dict[str, str]) -> set[str]:
    return {name for name in original if name == f"train {model}" or f" {model}/" in name}


def test_rewording_comments_and_docstrings_reruns_nothing(tree, original):
    assert changed_by_editing(tree, "pilotlab/strategies/prune.py", original, "\n# a comment, reworded\n\n") == set()
    path = tree / "pilotlab/predictor.py"
    text = path.read_text()
    path.write_text(text.replace('"""A pilotlab checkpoint (eager) or a TorchScript file."""',
                                 '"""A pilotlab checkpoint (eager), or a TorchScript file: reworded."""', 1))
    try:
        assert text != path.read_text() and plan_keys(tree) == original
    finally:
        path.write_text(text)


def test_editing_a_strategy_reruns_only_its_jobs(tree, original):
    changed = changed_by_editing(tree, "pilotlab/strategies/prune.py", original)
    # local_prune is defined there, and the shape of the l1_pruning network it shares with prune_quant
    assert changed == {name for name in original if "/local_prune" in name or "/prune_quant" in name
                       or name.startswith("prepare ") and "/l1_pruning" in name}
    assert any(name.startswith("online pilotnet/local_prune") for name in changed)


def test_adding_a_strategy_as_the_docs_say_reruns_no_other_strategy(tree, original):
    """Outside test: docs/strategies.md had the new config module added to configs/__init__.py's imports,
    which is in every optimize job's code: every strategy's jobs ran again."""
    added = [tree / "pilotlab/strategies/configs/my_prune.py", tree / "pilotlab/strategies/my_prune.py"]
    added[0].write_text("from dataclasses import dataclass\nfrom pilotlab.strategies.registry import register_strategy\n"
                        "@dataclass(frozen=True)\nclass MyPruneConfig:\n    amount: float = 0.3\n    version: int = 1\n"
                        "register_strategy('my_prune', MyPruneConfig, 'pilotlab.strategies.my_prune:my_prune')\n")
    added[1].write_text("def my_prune(config, source):\n    return {}\n")
    try:
        assert plan_keys(tree) == original
        known = subprocess.run([sys.executable, "-c", "from pilotlab.strategies import STRATEGIES; "
                                "print('my_prune' in STRATEGIES.names())"], cwd=tree, capture_output=True, text=True,
                               env={"PYTHONPATH": python_path(tree), "PATH": "/usr/bin:/bin"}, timeout=120)
        assert known.stdout.strip() == "True", known.stderr      # registered without an edit elsewhere
    finally:
        for path in added:
            path.unlink()


def test_editing_a_helper_imported_inside_a_handler_reruns_its_strategy(tree, original):
    changed = changed_by_editing(tree, "pilotlab/strategies/kmeans.py", original)
    assert changed == {name for name in original if "/cluster" in name}


def test_editing_training_code_reruns_training_and_what_follows(tree, original):
    changed = changed_by_editing(tree, "pilotlab/training.py", original)
    assert {"train pilotnet", "train stacked"} <= changed
    assert changed == {name for name in original if not name.startswith(("record", "frames", "online explicit",
                                                                        "online expert"))}


def test_editing_a_network_reruns_the_models_built_on_it(tree, original):
    stacked = changed_by_editing(tree, "pilotlab/models/pilotnet_stacked.py", original)
    assert stacked == jobs_of_model("stacked", original) and "train stacked" in stacked
    pilotnet = changed_by_editing(tree, "pilotlab/models/pilotnet.py", original)   # PilotNetStacked subclasses it
    assert pilotnet == jobs_of_model("pilotnet", original) | jobs_of_model("stacked", original)


def test_editing_the_offline_job_reruns_only_the_offline_jobs(tree, original):
    """An offline job measures MSE beside its timing job's figures: neither the timings nor the laps that
    replay them stand on its code."""
    changed = changed_by_editing(tree, "pilotlab/jobs/offline.py", original)
    assert changed == {name for name in original if name.startswith("offline ")} and changed


def test_editing_how_networks_are_timed_reruns_the_timings_and_what_reads_them(tree, original):
    changed = changed_by_editing(tree, "pilotlab/jobs/timing.py", original)
    network_laps = {name for name in original if name.startswith("online ") and "/" in name}
    assert changed == {name for name in original if name.startswith(("timing ", "offline "))} | network_laps


def test_editing_the_simulator_reruns_recordings_and_laps(tree, original):
    changed = changed_by_editing(tree, "pilotlab/sim/car.py", original)
    assert changed == set(original) and "online expert on cpu at simple_circuit cw" in changed
