"""Plan cost follows jobs, not cells (issue 25): prints the seconds and the peak memory of planning

- a grid of identical entries: 1000 models × 250 strategies × 2 hardware × 2 circuits (1,000,000 cells,
  22 jobs; target ≤ 10 s and ≤ 1 GB), and
- a recipe of distinct entries: 100 models × 100 strategies × 2 hardware × 4 circuits (80,000 cells,
  about 130,000 jobs; target ≤ 5 s).

Each is planned in a fresh interpreter (so its peak memory is its own): seconds of load + plan, the
process's peak resident memory (imports included) and, where `perf` is installed, the instructions it ran
(a steadier measure than seconds on a shared machine). Never asserts timings.
Run: python -m pytest -m benchmark -s tests/pilotlab/test_plan_benchmark.py
"""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.child import python_path

ROOT = Path(__file__).resolve().parents[2]
PLAN = """
import json, sys, time
from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.domain import DOMAIN
def peak_kb():  # this program's high-water mark (ru_maxrss would count the pytest process it was forked from)
    return int(next(line for line in open("/proc/self/status") if line.startswith("VmHWM")).split()[1])
engine.register_kinds(DOMAIN)
started = time.perf_counter()
recipe = load_recipe(sys.argv[1], DOMAIN)
plan = engine.make_plan(recipe, DOMAIN, Store(sys.argv[2]))
seconds = time.perf_counter() - started
print(json.dumps({"seconds": seconds, "cells": recipe.grid.count(), "jobs": len(plan.statuses),
                  "peak_mb": peak_kb() / 1024}))
"""


def recipe(path: Path, models: int, strategies: int, circuits: list[str], distinct: bool) -> Path:
    lines = ["name: bench", "datasets:", "  train: {record: {circuits: [simple_circuit], laps: 1}}",
             "  test: {record: {circuits: [simple_circuit], laps: 0.5}}", "models:"]
    lines += [f"  m{i}: {{arch: pilotnet, epochs: {i + 1 if distinct else 1}}}" for i in range(models)]
    lines += ["strategies:"] + [f"  s{i}: {{use: local_prune, conv: {(i + 1) / 1000 if distinct else 0.3}}}"
                                for i in range(strategies)]
    lines += ["matrix:", f"  model: [{', '.join(f'm{i}' for i in range(models))}]",
              f"  strategy: [{', '.join(f's{i}' for i in range(strategies))}]",
              "  hardware: [cpu, cpu1]", f"  circuit: [{', '.join(circuits)}]"]
    path.write_text("\n".join(lines) + "\n")
    return path


def planned(path: Path, store: Path) -> dict:
    """The child's figures; with `perf` on the machine, also the instructions it ran (user mode, imports
    included): a count that moves well under 1 % between runs where wall time on a shared machine can
    move by a quarter, so two versions of the planner compare by it."""
    perf = shutil.which("perf")
    counted = store.parent / "perf.csv"
    prefix = [perf, "stat", "-x", ",", "-e", "instructions:u", "-o", str(counted)] if perf else []
    out = _plan_child(prefix, path, store)
    if out.returncode != 0 and perf:    # perf refused (perf_event_paranoid): plan without it
        perf, out = None, _plan_child([], path, store)
    assert out.returncode == 0, out.stderr
    figures = json.loads(out.stdout.splitlines()[-1])
    if perf and counted.exists():
        count = next((line.split(",")[0] for line in counted.read_text().splitlines() if "instructions" in line), "")
        figures["instructions"] = int(count) if count.isdigit() else None   # "<not supported>" in some VMs
    return figures


def _plan_child(prefix: list[str], path: Path, store: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*prefix, sys.executable, "-c", PLAN, str(path), str(store)], cwd=ROOT,
                          capture_output=True, text=True, env={"PYTHONPATH": python_path(ROOT),
                                                              "PATH": "/usr/bin:/bin", "HOME": str(store.parent)})


@pytest.mark.benchmark
@pytest.mark.parametrize("name, models, strategies, circuits, distinct, target", [
    ("identical entries", 1000, 250, ["simple_circuit", "montreal"], False, "≤ 10 s, ≤ 1 GB"),
    ("distinct entries", 100, 100, ["simple_circuit", "montreal", "montmelo", "nurburgring"], True, "≤ 5 s"),
])
def test_plan_cost_follows_jobs(tmp_path, name, models, strategies, circuits, distinct, target):
    figures = planned(recipe(tmp_path / "r.yaml", models, strategies, circuits, distinct), tmp_path / "store")
    counted = f", {figures['instructions'] / 1e9:.2f} G instructions" if figures.get("instructions") else ""
    print(f"\nplan of {name}: {figures['cells']:,} cells, {figures['jobs']:,} jobs: {figures['seconds']:.2f} s, "
          f"peak {figures['peak_mb']:.0f} MB{counted} (target {target})")
    assert figures["cells"] == models * strategies * 2 * len(circuits)
