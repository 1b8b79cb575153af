"""A hardware profile that names the Dask worker resource of its machine (`hardware: {jetson: {threads: 1,
worker_resource: JETSON}}`): its timing jobs go only to the workers declaring it, are planned for no
particular host (the result records the one that timed), and its laps replay those timings anywhere."""
import pytest

from matrix import RecipeError, engine
from matrix.kinds import KINDS
from matrix.recipe import load_recipe
from pilotlab.domain import DOMAIN
from pilotlab.hardware import host_fingerprint

RECIPE = """\
name: lab
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.1}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 5}}
models:
  pilotnet: {epochs: 1, batch_size: 32}
hardware:
  jetson: {threads: 1, worker_resource: JETSON}
online: {references: [expert], timing: TIMING}
matrix:
  model: [pilotnet]
  strategy: [baseline]
  hardware: [cpu1, jetson]
  circuit: [simple_circuit]
"""


def plan(tmp_path, timing="replay", text=RECIPE):
    path = tmp_path / "recipe.yaml"
    path.write_text(text.replace("TIMING", timing))
    return {job.name: job for job in engine.plan_jobs(load_recipe(path, DOMAIN), DOMAIN)}


def resources(job) -> dict:
    return dict(KINDS.get(job.kind).resources_for(job.params))


def test_its_timing_jobs_go_to_its_machine_and_its_laps_replay_them_anywhere(tmp_path):
    jobs = plan(tmp_path)
    jetson, here = jobs["timing pilotnet/baseline on jetson"], jobs["timing pilotnet/baseline on cpu1"]
    assert resources(jetson) == {"JETSON": 1} and jetson.params["host"] is None
    assert jetson.params["hardware"] == {"name": "jetson", "device": "cpu", "threads": 1, "worker_resource": "JETSON"}
    assert resources(here) == {} and here.params["host"] == host_fingerprint()
    offline = jobs["offline pilotnet/baseline on jetson"]   # its MSE: any worker, beside other jobs
    assert offline.deps["timing"] is jetson and resources(offline) == {} and offline.params["host"] is None
    lap = jobs["online pilotnet/baseline on jetson at simple_circuit cw"]
    assert lap.deps["timing"] is jetson and resources(lap) == {} and lap.params["host"] is None


def test_a_lap_that_reads_the_clock_goes_to_its_machine_too(tmp_path):
    lap = plan(tmp_path, timing="measured")["online pilotnet/baseline on jetson at simple_circuit cw"]
    assert resources(lap) == {"JETSON": 1}


def test_a_bad_resource_name_is_the_recipes_error(tmp_path):
    with pytest.raises(RecipeError, match=r"recipe.yaml:8: hardware\.jetson\.worker_resource: "
                                         r"'JETSON=1' is not a Dask resource name"):
        plan(tmp_path, text=RECIPE.replace("worker_resource: JETSON", "worker_resource: JETSON=1"))
