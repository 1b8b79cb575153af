"""A small pilotlab recipe on a Dask LocalCluster (two worker processes) gives the local executor's
jobs and results (timings apart), and the local executor then finds everything fresh."""
import math

import pytest

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.columns import OFFLINE, ONLINE
from pilotlab.domain import DOMAIN

pytest.importorskip("distributed")

RECIPE = """\
name: dask-pipeline
datasets:
  train: {record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 0.1, camera: {width: 320, height: 240}}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 5, camera: {width: 320, height: 240}}}
models:
  pilotnet: {epochs: 1, batch_size: 32}
online: {timeout_s: 4, references: [expert]}
matrix:
  model: [pilotnet]
  strategy: [baseline, dynamic_quant]
  hardware: [cpu1]
  circuit: [simple_circuit]
"""
TIMINGS = {"latency_ms", "latency_p90_ms", "latency_p99_ms", "latency_runs", "throughput_ips", "peak_mem_mb",
           "brain_frequency_real_hz", "mean_inference_ms", "real_time_factor", "seconds", "wall_seconds",
           "measured_inference_ms", "wall_seconds", "decode_fps", "duration_s", "bytes"}
COMPARED = {c.name for c in OFFLINE + ONLINE} - TIMINGS | {"val_mse", "val_mse_mean_predictor", "frames", "size_mb"}


def results(store: Store, plan) -> dict:
    return {s.job.name: store.result(s.job.key) for s in plan.statuses}


def same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9)
    return a == b


@pytest.mark.slow
def test_dask_local_cluster_matches_the_local_executor(tmp_path):
    path = tmp_path / "recipe.yaml"
    path.write_text(RECIPE)
    recipe = load_recipe(path, DOMAIN)
    local, remote = Store(tmp_path / "local"), Store(tmp_path / "dask")
    local_plan = engine.make_plan(recipe, DOMAIN, local)
    assert not engine.run_plan(local_plan, DOMAIN, local, jobs=2).failed
    remote_plan = engine.make_plan(recipe, DOMAIN, remote)
    summary = engine.run_plan(remote_plan, DOMAIN, remote, executor=engine.Executor("dask-local", 2))
    assert not summary.failed, summary.outcomes
    assert sorted(local.keys()) == sorted(remote.keys())
    ours, theirs = results(local, local_plan), results(remote, remote_plan)
    for name, result in ours.items():
        assert result["status"] == theirs[name]["status"], name
        for metric in COMPARED & set(result["value"]):
            assert same(result["value"][metric], theirs[name]["value"][metric]), (name, metric)
    assert not engine.make_plan(recipe, DOMAIN, remote).stale
