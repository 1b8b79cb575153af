"""A small pilotlab recipe on a Dask LocalCluster (two worker processes) gives the local executor's
jobs and results (measurements apart), and the local executor then finds everything fresh."""
import math

import pytest

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.columns import BEHAVIORMETRICS, OFFLINE, ONLINE
from pilotlab.domain import DOMAIN

pytest.importorskip("distributed")

RECIPE = """\
name: dask-pipeline
datasets:
  train: {record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 0.1, camera: {width: 320, height: 240}}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 5, camera: {width: 320, height: 240}}}
models:
  pilotnet: {epochs: 1, batch_size: 32}
online: {timeout_s: 4, references: [expert], timing: lockstep}   # lockstep: laps do not depend on timings
matrix:
  model: [pilotnet]
  strategy: [baseline, dynamic_quant]
  hardware: [cpu1]
  circuit: [simple_circuit]
"""
COLUMNS = OFFLINE + ONLINE + BEHAVIORMETRICS
# measurements (timings, memory) differ from run to run: only their presence is compared
MEASURED = {c.name for c in COLUMNS if c.measured}
COMPARED = {c.name for c in COLUMNS if not c.measured} | {"val_mse", "val_mse_mean_predictor", "frames"}


def results(store: Store, plan) -> dict:
    return {s.job.name: store.result(s.job.key) for s in plan.statuses}


def same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9)
    return a == b


def assert_same_results(ours: dict, theirs: dict) -> None:
    """Every job's status and every result that is not a measurement equal; each measurement given by both
    runs or by neither."""
    for name, result in ours.items():
        assert result["status"] == theirs[name]["status"], name
        mine, other = result["value"], theirs[name]["value"]
        for metric in COMPARED & set(mine):
            assert same(mine[metric], other.get(metric)), (name, metric, mine[metric], other.get(metric))
        for metric in MEASURED & set(mine):
            assert (mine[metric] is None) == (other.get(metric) is None), (name, metric)


@pytest.mark.slow
def test_dask_local_cluster_matches_the_local_executor(tmp_path, pipeline_one_at_a_time):
    recipe, local, local_plan = pipeline_one_at_a_time       # the local executor, one job at a time
    remote = Store(tmp_path / "dask")
    remote_plan = engine.make_plan(recipe, DOMAIN, remote)
    summary = engine.run_plan(remote_plan, DOMAIN, remote, executor=engine.Executor("dask-local", 2))
    assert not summary.failed, summary.outcomes
    assert sorted(local.keys()) == sorted(remote.keys())
    assert_same_results(results(local, local_plan), results(remote, remote_plan))
    assert not engine.make_plan(recipe, DOMAIN, remote).stale


LAB = """\
name: dask-lab
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.1, camera: {width: 320, height: 240}}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 5, camera: {width: 320, height: 240}}}
models:
  pilotnet: {epochs: 1, batch_size: 32}
hardware:
  jetson: {threads: 1, worker_resource: JETSON}
online: {timeout_s: 4, references: [expert]}
matrix:
  model: [pilotnet]
  strategy: [baseline]
  hardware: [jetson]
  circuit: [simple_circuit]
"""


@pytest.mark.slow
def test_a_profile_times_on_the_dask_worker_of_its_machine_and_its_lap_replays_those_timings(tmp_path):
    import distributed
    import numpy as np

    def worker(host: str, resources: dict) -> dict:   # a worker process that is `host` to pilotlab
        env = {"MATRIX_HOST": host, "MATRIX_HOST_LOCK": str(tmp_path / f"{host}.lock")}
        return {"cls": distributed.Nanny, "options": {"nthreads": 1, "resources": resources, "env": env}}
    path = tmp_path / "recipe.yaml"
    path.write_text(LAB)
    store = Store(tmp_path / "store")
    plan = engine.make_plan(load_recipe(path, DOMAIN), DOMAIN, store)
    workers = {"jetson": worker("jetson", {"JETSON": 1}), "lab": worker("lab", {})}
    summary = None
    try:
        with distributed.SpecCluster(workers=workers, scheduler={"cls": distributed.Scheduler, "options": {
                "dashboard_address": None}}) as cluster, distributed.Client(cluster) as client:
            from matrix.dask_executor import run_dask
            summary = run_dask(plan.statuses, store, client, kind_modules=DOMAIN.kind_modules)
    except TimeoutError:
        # closing the cluster, not the run: in CI this suite runs at nice 19 beside the README's pytest, and a
        # starved worker process took longer than distributed's fixed 5 s (Nanny.close) to exit
        if summary is None:
            raise
    assert not summary.failed, summary.outcomes
    done = results(store, plan)
    timing = done["timing pilotnet/baseline on jetson"]["value"]
    assert timing["hostname"] == "jetson" and timing["hardware"]["worker_resource"] == "JETSON"
    assert done["offline pilotnet/baseline on jetson"]["value"]["hostname"] == "jetson"   # the timing's figures
    timed = next(s.job for s in plan.statuses if s.job.name == "timing pilotnet/baseline on jetson")
    samples = np.load(store.artifacts(timed.key) / timing["latency_samples"])
    lap = done["online pilotnet/baseline on jetson at simple_circuit cw"]["value"]
    assert lap["replayed_latency_samples"] == len(samples)
    assert lap["replayed_latency_ms"] == round(float(np.median(samples)), 4)
