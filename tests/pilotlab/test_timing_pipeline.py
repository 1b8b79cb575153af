"""Slow: the tiniest recipe end to end (`pilotlab run` as a user runs it): each network is timed by a
timing job, which its laps replay and its offline rows show, and an edit of the test set reruns its
recording and the offline jobs only: no network is timed again and no lap is driven again."""
from __future__ import annotations

import json
import re
import subprocess

import numpy as np
import pytest

from matrix.store import Store
from tests.child import run_pilotlab

RECIPE = """
name: tiny_timing
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.1, camera: {width: 160, height: 120}}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 2, camera: {width: 160, height: 120}}}
models:
  pilotnet: {arch: pilotnet, epochs: 1, val_fraction: 0}
online: {timeout_s: 2, references: [], camera: {width: 160, height: 120}}
matrix:
  model: [pilotnet]
  strategy: [baseline]
  hardware: [cpu1]
  circuit: [simple_circuit]
"""


pilotlab = run_pilotlab


def ran(run: subprocess.CompletedProcess) -> set[str]:
    """The kinds of the jobs a run ran (its "✓ <name> <seconds>s" progress lines, on stderr)."""
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return {m.group(1).split()[0] for m in re.finditer(r"^✓ (.+?) [\d.]+s$", run.stderr, re.M)}


@pytest.mark.slow
def test_laps_replay_the_timing_job_and_a_test_set_edit_times_nothing_again(tmp_path):
    recipe = tmp_path / "timing.yaml"
    recipe.write_text(RECIPE)
    assert ran(pilotlab("run", "timing.yaml", "--store", "store", cwd=tmp_path)) == {
        "record", "frames", "train", "optimize", "timing", "offline", "online"}
    plan = json.loads(pilotlab("plan", "timing.yaml", "--store", "store", "--json", cwd=tmp_path).stdout)
    jobs = {job["name"]: job for job in plan}
    store = Store(tmp_path / "store")
    timing = jobs["timing pilotnet/baseline on cpu1"]
    lap = store.spec(jobs["online pilotnet/baseline on cpu1 at simple_circuit cw"]["key"])
    assert lap["deps"]["timing"] == timing["key"] and "scale_reference" not in lap["deps"]
    assert not any(job["kind"] == "offline" and job["key"] in json.dumps(lap["deps"]) for job in plan)
    timed = store.result(timing["key"])["value"]
    samples = store.artifacts(timing["key"]) / timed["latency_samples"]
    assert samples.is_file() and "mse" not in timed and timed["hostname"]

    rows = json.loads((tmp_path / "reports" / "tiny_timing" / "results.json").read_text())["rows"]
    offline = next(row for row in rows if row["kind"] == "offline")
    assert offline["latency_ms"] == timed["latency_ms"] and offline["throughput_ips"] == timed["throughput_ips"]
    assert offline["mse"] is not None and offline["size_mb"] > 0
    network_lap = next(row for row in rows if row["kind"] == "online")
    assert network_lap["status"] == "ok" and network_lap["mean_inference_ms"] is not None
    replayed = store.result(jobs["online pilotnet/baseline on cpu1 at simple_circuit cw"]["key"])["value"]
    assert replayed["latency_source"] == "timing job"
    assert replayed["replayed_latency_samples"] == len(np.load(samples)) == timed["latency_runs"]
    readme = (tmp_path / "reports" / "tiny_timing" / "README.md").read_text()
    assert f"{timed['latency_ms']:.2f}" in readme

    times = pilotlab("status", "--times", "--store", "store", cwd=tmp_path)
    assert times.returncode == 0 and re.search(r"\btiming\b", times.stdout), times.stdout

    recipe.write_text(RECIPE.replace("seed: 2", "seed: 3"))   # another test set
    assert ran(pilotlab("run", "timing.yaml", "--store", "store", cwd=tmp_path)) == {"record", "frames", "offline"}
    assert store.result(timing["key"])["value"] == timed
    forced = ran(pilotlab("run", "timing.yaml", "--store", "store", "--force", "timing", cwd=tmp_path))
    assert "timing" in forced and forced <= {"timing", "offline", "online"}   # what shows or replays it, if it moved
