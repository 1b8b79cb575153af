"""A warm rerun is quick: planning (`pilotlab plan`, and `run` before it runs anything) and `--help`
import none of the heavy libraries; only the jobs' handlers do (torch alone takes ~2 s to import), and
a strategy's handler only when the strategy is applied (its config is what planning imports)."""
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pilotlab.strategies import STRATEGIES

HEAVY = {"torch", "torchao", "onnx", "onnxruntime", "tensorflow", "onnx2tf", "ai_edge_litert", "matplotlib", "cv2",
         "pybullet", "rosbags", "gymnasium"}
HANDLERS = {entry.module for _, entry in STRATEGIES.items()}
ROOT = Path(__file__).resolve().parents[3]
RECIPE = """
name: light
datasets:
  train: {{record: {{circuits: [simple_circuit], directions: [cw, ccw], laps: 0.2}}}}
  test: {{record: {{circuits: [simple_circuit], laps: 0.1, seed: 2}}}}
models:
  pilotnet: {{arch: pilotnet, epochs: 1}}
  stacked: {{arch: pilotnet_stacked, options: {{frames: 2}}, epochs: 1}}
strategies:
  prune_more: {{use: local_prune, conv: 0.5}}
matrix:
  model: [pilotnet, stacked]
  strategy: [{strategies}, prune_more]
  hardware: [cpu, cuda]
  circuit: [simple_circuit]
"""


def pilotlab(tmp_path, *argv: str, timeout: float = 120) -> tuple[subprocess.CompletedProcess, set[str]]:
    """Run the command line in a fresh interpreter; (the process, the modules it imported)."""
    modules = tmp_path / "modules.json"
    process = subprocess.run([sys.executable, "-m", "tests.pilotlab.cli.imports_after", str(modules), *argv],
                             cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    return process, set(json.loads(modules.read_text()))


def test_plan_imports_no_heavy_library(tmp_path):
    recipe = tmp_path / "light.yaml"
    recipe.write_text(RECIPE.format(strategies=", ".join(STRATEGIES.names())))
    process, modules = pilotlab(tmp_path, "plan", str(recipe), "--json", "--store", str(tmp_path / "store"))
    assert process.returncode == 0, process.stderr
    jobs = json.loads(process.stdout)
    assert {job["kind"] for job in jobs} == {"record", "frames", "train", "prepare", "optimize", "timing", "offline",
                                            "online"}
    assert {"pilotlab.strategies.configs.pt2e", "pilotlab.models.configs", "pilotlab.specs.online"} <= modules
    assert modules & HEAVY == set()
    assert modules & HANDLERS == set()       # named by string, imported when a strategy is applied


def test_planning_the_study_imports_no_heavy_library(tmp_path):
    """Issue 26: `pilotlab plan recipes/study2022.yaml` imports neither torch, onnx, onnxruntime nor
    tensorflow, nor numpy (0.1 s of the 0.5 s start-up: circuit and strategy names come from registries
    that hold names, configs and file names; what a circuit's geometry or a strategy's handler needs is
    imported when one is built or applied). Its start-up, interpreter start to plan done, is printed
    (target < 0.5 s on a quiet machine; the bound here only catches a heavy import sneaking back)."""
    started = time.perf_counter()
    process, modules = pilotlab(tmp_path, "plan", str(ROOT / "recipes" / "study2022.yaml"), "--json",
                                "--store", str(tmp_path / "store"))
    seconds = time.perf_counter() - started
    assert process.returncode == 0, process.stderr
    assert len(json.loads(process.stdout)) > 100
    print(f"\n`pilotlab plan recipes/study2022.yaml` in a fresh interpreter: {seconds:.2f} s (target < 0.5 s)")
    assert modules & HEAVY == set() and modules & HANDLERS == set()
    assert "numpy" not in modules
    assert "pilotlab.report.data" not in modules   # a study to compare with is a name to plan, not its rows
    assert "rich" not in modules and "multiprocessing" not in modules   # --json prints no table, runs no job
    assert seconds < 20


def test_help_imports_no_heavy_library(tmp_path):
    process, modules = pilotlab(tmp_path, "--help")
    assert process.returncode == 0 and "plan" in process.stdout
    assert modules & HEAVY == set()


TINY = """
name: tiny
datasets:
  train: {{record: {{circuits: [simple_circuit], laps: 0.1, camera: {{width: 160, height: 120}}}}}}
  test: {{record: {{circuits: [simple_circuit], laps: 0.05, seed: 2, camera: {{width: 160, height: 120}}}}}}
models:
  pilotnet: {{arch: pilotnet, epochs: 1, val_fraction: 0}}
online: {{timeout_s: 2, references: []}}
report: {{folder: {reports}}}
matrix:
  model: [pilotnet]
  strategy: [baseline]
  circuit: [simple_circuit]
"""


@pytest.mark.slow
def test_a_warm_rerun_imports_no_heavy_library(tmp_path):
    recipe = tmp_path / "tiny.yaml"
    recipe.write_text(TINY.format(reports=tmp_path / "reports"))
    argv = ("run", str(recipe), "--store", str(tmp_path / "store"))
    cold, _ = pilotlab(tmp_path, *argv, timeout=900)
    assert cold.returncode == 0, cold.stderr
    assert (tmp_path / "reports" / "tiny" / "README.md").is_file()
    warm, modules = pilotlab(tmp_path, *argv)
    assert warm.returncode == 0 and "nothing to do" in warm.stdout + warm.stderr
    assert modules & HEAVY == set()          # the report is up to date: not even matplotlib
