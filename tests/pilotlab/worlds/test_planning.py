"""A recipe's world axis: recordings, offline test sets and laps in BM worlds, keyed by the worlds' files."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from matrix import RecipeError, engine
from matrix.recipe import load_recipe
from pilotlab.domain import DOMAIN

RECIPE = """\
name: worlds-test
worlds: {{assets: {assets}}}
datasets:
  train: {{record: {{worlds: [oval], directions: [cw, ccw], laps: 0.2}}}}
  test: {{record: {{worlds: [oval], laps: 0.1, seed: 3}}}}
models:
  small: {{epochs: 1}}
matrix:
  model: [small]
  strategy: [baseline, dynamic_quant]
  world: [oval, oval_no_sun]
"""


def plan(tmp_path: Path, assets: Path, text: str = RECIPE) -> dict:
    path = tmp_path / "recipe.yaml"
    path.write_text(text.format(assets=assets))
    return {job.name: job for job in engine.plan_jobs(load_recipe(path, DOMAIN), DOMAIN)}


def test_the_world_axis_records_tests_and_drives_in_each_world(tmp_path, oval_assets):
    jobs = plan(tmp_path, oval_assets)
    record = jobs["record train/oval cw"]
    assert record.params["world"] == "oval" and record.params["circuit"] == "oval"   # its CSV by stem, as an input
    assert set(record.inputs) == {"world", "circuit_csv"} and record.inputs["world"].path.endswith("oval.world")
    assert record.inputs["circuit_csv"].path.endswith("oval.csv")
    shifted = jobs["offline small/dynamic_quant on cpu in oval_no_sun"]
    assert shifted.labels["test_set"] == "test in oval_no_sun" and shifted.labels["world"] == "oval_no_sun"
    assert [dep.params["world"] for dep in shifted.deps["test"][0].dep_jobs()] == ["oval_no_sun"]
    lap = jobs["online small/baseline on cpu at oval_no_sun cw"]
    assert lap.params["world"] == "oval_no_sun" and lap.labels["circuit"] == "oval_no_sun"
    assert {"online explicit on cpu at oval cw", "online expert on cpu at oval_no_sun cw"} <= set(jobs)


def test_a_world_recorded_beside_the_circuit_of_its_name_is_named_apart(tmp_path, oval_assets):
    """Outside test: `record: {circuits: [simple_circuit], worlds: [simple_circuit]}` made two jobs of one
    name, an error that called itself a bug in the planner."""
    (tmp_path / "circuits").mkdir()
    shutil.copy(oval_assets / "worlds" / "oval.csv", tmp_path / "circuits" / "oval.csv")
    jobs = plan(tmp_path, oval_assets, RECIPE.replace("{{worlds: [oval], directions", "{{circuits: [oval], worlds: [oval], directions"))
    assert "world" not in jobs["record train/oval cw"].params
    assert jobs["record train/oval (BM world) cw"].params["world"] == "oval"
    assert "frames train/oval (BM world) ccw" in jobs


def test_a_network_tested_in_several_worlds_is_timed_once_and_every_lap_replays_that_timing(tmp_path, oval_assets):
    jobs = plan(tmp_path, oval_assets)
    timing = jobs["timing small/dynamic_quant on cpu"]
    assert [dep.params["world"] for dep in timing.deps["frames"][0].dep_jobs()] == ["oval"]   # the training frames
    for world in ("oval", "oval_no_sun"):   # each its own test set, one timing
        assert jobs[f"offline small/dynamic_quant on cpu in {world}"].deps["timing"] is timing
        assert jobs[f"online small/dynamic_quant on cpu at {world} cw"].deps["timing"] is timing
    assert sum(job.kind == "timing" for job in jobs.values()) == 2   # one per strategy


def test_an_edit_of_a_world_reruns_only_what_drove_there(tmp_path, oval_assets):
    assets = shutil.copytree(oval_assets, tmp_path / "assets")
    before = {name: job.key for name, job in plan(tmp_path, assets).items()}
    world = assets / "worlds" / "oval_no_sun.world"
    world.write_text(world.read_text().replace("<speed>12</speed>", "<speed>11</speed>"))
    after = {name: job.key for name, job in plan(tmp_path, assets).items()}
    changed = sorted(name for name in before if before[name] != after[name])
    assert changed and all("oval_no_sun" in name for name in changed)


def test_moved_worlds_rerun_nothing(tmp_path, oval_assets):
    """Outside test: a world's centreline CSV went into the params by its absolute path, so moving BM's
    assets (another clone, another machine) reran every job that drove there."""
    before = {name: job.key for name, job in plan(tmp_path, shutil.copytree(oval_assets, tmp_path / "a")).items()}
    after = {name: job.key for name, job in plan(tmp_path, shutil.copytree(oval_assets, tmp_path / "b")).items()}
    assert before == after


def test_no_world_no_change_to_the_keys_of_pilotlab_s_own_world():
    """Jobs without a world leave the field out of their params (the keys stay what they were)."""
    from pilotlab.specs.online import OnlineSpec
    from pilotlab.specs.record import RecordSpec
    assert "world" not in RecordSpec(circuit="simple_circuit").model_dump(mode="json")
    assert "world" not in OnlineSpec(circuit="simple_circuit").model_dump(mode="json")


@pytest.mark.parametrize("edit, message, where", [
    (("world: [oval, oval_no_sun]", "world: [oval, ovl]"), "did you mean 'oval'", "matrix.world"),
    (("world: [oval, oval_no_sun]", "world: [oval]\n  circuit: [simple_circuit]"), "names a circuit and a world",
     "matrix"),
    (("worlds: {{assets: {assets}}}\n", ""), "has no `worlds: {assets: DIR}`", "matrix.world"),
    (("worlds: {{assets: {assets}}}\n", "worlds: {{assets: ../missing}}\n"),
     r"../missing does not exist .* or set \$PILOTLAB_BM_ASSETS", "worlds.assets"),   # a shipped recipe copied away
])
def test_recipe_errors_name_the_key(tmp_path, oval_assets, monkeypatch, edit, message, where):
    monkeypatch.delenv("PILOTLAB_BM_ASSETS", raising=False)
    with pytest.raises(RecipeError, match=message) as error:
        plan(tmp_path, oval_assets, RECIPE.replace(*edit))
    assert where in str(error.value)


def test_a_bad_assets_folder_from_the_environment_says_so(tmp_path, oval_assets, monkeypatch):
    """Outside test: $PILOTLAB_BM_ASSETS standing in for a recipe's missing folder, itself wrong, was said as
    "BehaviorMetrics assets folder /nonexist: no such folder", a path the recipe does not hold."""
    monkeypatch.setenv("PILOTLAB_BM_ASSETS", str(tmp_path / "nonexist"))
    with pytest.raises(RecipeError, match=r"no such folder .*\(the assets folder is \$PILOTLAB_BM_ASSETS, standing in "
                                          r"for worlds.assets: \.\./missing, which does not exist\)"):
        plan(tmp_path, oval_assets, RECIPE.replace("worlds: {{assets: {assets}}}\n", "worlds: {{assets: ../missing}}\n"))
    with pytest.raises(RecipeError, match=r"no such folder .*\(the assets folder is \$PILOTLAB_BM_ASSETS\)"):
        plan(tmp_path, oval_assets, RECIPE.replace("worlds: {{assets: {assets}}}\n", ""))
