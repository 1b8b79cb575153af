"""Slow: two `pilotlab run` of one recipe in one folder at once, as two people (or a CI job and a
person) might start them: both finish with exit 0, each job runs once, the report is whole, and no
job that runs alone (the timing jobs, the training; laps that replay timings run beside others)
overlaps another job."""
import importlib
import re
import subprocess
import sys
from datetime import datetime
from pathlib import Path

import pytest

from matrix.kinds import KINDS
from matrix.store import Store
from pilotlab.specs import KIND_MODULES
from tests.child import python_path

for _module in KIND_MODULES:   # registers pilotlab's job kinds
    importlib.import_module(_module)

ROOT = Path(__file__).resolve().parents[2]
TINY = """
name: tiny
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.1, camera: {width: 160, height: 120}}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 2, camera: {width: 160, height: 120}}}
models:
  pilotnet: {arch: pilotnet, epochs: 1, val_fraction: 0}
online: {timeout_s: 2, references: [explicit]}
matrix:
  model: [pilotnet]
  strategy: [baseline, dynamic_quant]
  circuit: [simple_circuit]
"""
STAMP = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}) ")


def span(log: Path) -> tuple[datetime, datetime]:
    stamps = [m.group(1) for line in log.read_text(errors="replace").splitlines() if (m := STAMP.match(line))]
    first, last = (datetime.strptime(s, "%Y-%m-%d %H:%M:%S,%f") for s in (stamps[0], stamps[-1]))
    return first, last


@pytest.mark.slow
def test_two_runs_of_one_recipe_in_one_folder(tmp_path):
    (tmp_path / "tiny.yaml").write_text(TINY)
    command = [sys.executable, "-m", "pilotlab", "run", "tiny.yaml", "--store", "store"]
    env = {**__import__("os").environ, "PYTHONPATH": python_path(ROOT)}
    runs = [subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                             env=env) for _ in range(2)]
    outputs = [run.communicate(timeout=1200)[0] for run in runs]
    assert [run.returncode for run in runs] == [0, 0], outputs
    ran = [m.group(1) for out in outputs for m in re.finditer(r"^✓ (.+?) [\d.]+s$", out, re.M)]
    assert len(ran) == len(set(ran)) and ran, outputs                   # each job ran in one run only
    assert (tmp_path / "reports" / "tiny" / "README.md").is_file()
    store = Store(tmp_path / "store")
    specs = {key: store.spec(key) or {} for key in store.keys()}
    spans = {key: (spec.get("kind"), span(store.job_dir(key) / "log.txt")) for key, spec in specs.items()}
    alone = [(key, spans[key][1]) for key, spec in specs.items() if KINDS.get(spec["kind"]).runs_alone(spec["params"])]
    assert {spans[key][0] for key, _ in alone} == {"timing", "train"}
    for key, (start, end) in alone:
        for other, (_, (o_start, o_end)) in spans.items():
            assert other == key or o_end <= start or o_start >= end, (key[:8], other[:8])

    # a stored model replaced by a file of the same size: stale "output changed", rebuilt, never loaded
    train = next(key for key, (kind, _) in spans.items() if kind == "train")
    model = store.artifacts(train) / "model.pt"
    model.write_bytes(bytes(model.stat().st_size))
    plan = subprocess.run([sys.executable, "-m", "pilotlab", "plan", "tiny.yaml", "--store", "store", "--json"],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=300)
    states = {row["key"]: (row["status"], row["reason"]) for row in __import__("json").loads(plan.stdout)}
    assert states[train] == ("stale", "output changed")
    rerun = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=900)
    assert rerun.returncode == 0 and re.search(r"^✓ train pilotnet [\d.]+s$", rerun.stdout + rerun.stderr, re.M), \
        rerun.stdout + rerun.stderr
    assert model.read_bytes() != bytes(model.stat().st_size)
