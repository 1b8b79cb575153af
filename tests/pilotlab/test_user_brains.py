"""A brain the user wrote, through the recipe path (planner -> online job in the store -> report) and
through `pilotlab drive --brain`: a proportional controller on the red line, written by the test."""
import json
import shutil

import pytest

from matrix import RecipeError, engine
from matrix.engine import Plan, run_plan
from matrix.recipe import load_recipe
from pilotlab.cli import main
from pilotlab.domain import DOMAIN
from pilotlab.report.recipe import report_folder, write_recipe_report
from pilotlab.usercode import source_hash
from tests.pilotlab.user_brains import write_red_line

SPEC = "brains/mine.py:RedLine"
RECIPE = """\
name: mine
datasets:
  train: {{record: {{circuits: [simple_circuit], laps: 0.1}}}}
  test: {{record: {{circuits: [simple_circuit], laps: 0.1, seed: 3}}}}
models:
  pilotnet: {{epochs: 1}}
online: {{timing: lockstep, {timeout}references: [explicit, expert, {{mine: {spec}}}]}}
report: {{folder: {reports}}}
matrix:
  model: [pilotnet]
  strategy: [baseline]
  circuit: [simple_circuit]
"""


def recipe_at(tmp_path, timeout_s: float | None = None, spec: str = SPEC):
    write_red_line(tmp_path)
    path = tmp_path / "mine.yaml"
    timeout = f"timeout_s: {timeout_s}, " if timeout_s else ""
    path.write_text(RECIPE.format(timeout=timeout, spec=spec, reports=tmp_path / "reports"))
    return load_recipe(path, DOMAIN)


def user_laps(jobs):
    return [job for job in jobs if job.kind == "online" and job.params.get("brain") == "user"]


def test_the_planner_makes_a_reference_lap_keyed_by_the_brain_s_source(tmp_path):
    recipe = recipe_at(tmp_path)
    jobs = engine.plan_jobs(recipe, DOMAIN)
    (lap,) = user_laps(jobs)
    assert lap.name == "online mine on cpu at simple_circuit cw"
    assert lap.labels == {"model": "reference", "strategy": "mine", "hardware": "cpu",
                          "circuit": "simple_circuit", "direction": "cw"}
    # the recipe's folder is not in the key (the lap finds it from its input brain_source)
    assert lap.params["user_brain"] == {"name": "mine", "spec": SPEC, "base": "."}
    assert lap.inputs["brain_source"].sha256 == source_hash(SPEC, tmp_path)
    keys = {job.name: job.key for job in jobs}
    brain = tmp_path / "brains" / "mine.py"
    brain.write_text(brain.read_text() + "\n# a comment: not code\n")
    assert {job.name: job.key for job in engine.plan_jobs(load_recipe(tmp_path / "mine.yaml", DOMAIN), DOMAIN)} == keys
    brain.write_text(brain.read_text() + "\nSPEED = 1.0\n")
    edited = {job.name: job.key for job in engine.plan_jobs(load_recipe(tmp_path / "mine.yaml", DOMAIN), DOMAIN)}
    assert {name for name in keys if keys[name] != edited[name]} == {lap.name}


@pytest.mark.parametrize("spec, message", [
    ("brains/none.py:RedLine", "mine.yaml:7: online.references.2.mine: brains/none.py: no such file"),
    ("brains/mine", "mine.yaml:7: online.references: mine: 'brains/mine': name your brain as file.py:Class"),
    # outside test: a typo'd class planned, then failed the lap in the run
    ("brains/mine.py:RedLin", "brains/mine.py has no 'RedLin' (did you mean 'RedLine'?); it defines: RedLine"),
])
def test_recipe_errors_about_a_user_brain_name_the_line(tmp_path, spec, message):
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, spec=spec), DOMAIN)
    assert message in str(caught.value) and "\n" not in str(caught.value)


def run_user_laps(tmp_path, timeout_s: float | None):
    """Run the recipe's user-brain lap in a real store through the engine, then write the report."""
    recipe = recipe_at(tmp_path, timeout_s)
    store = engine.open_store(DOMAIN, tmp_path / "store")
    plan = engine.make_plan(recipe, DOMAIN, store)
    mine = Plan(recipe, [status for status in plan.statuses if status.job in user_laps([status.job])])
    summary = run_plan(mine, DOMAIN, store)
    assert [outcome.status for outcome in summary.outcomes] == ["ok"], summary
    (lap,) = [status.job for status in mine.statuses]
    write_recipe_report(recipe, store, [status.job for status in plan.statuses])
    return store.result(lap.key)["value"], report_folder(recipe)


def test_a_moved_project_keeps_its_user_brain_s_lap_which_runs_from_the_new_folder(tmp_path):
    """Outside test: the lap was keyed by the recipe's absolute folder, so a project moved (or a second
    clone sharing the store) drove its user brains' laps again."""
    recipe_at(tmp_path / "a", timeout_s=0.5)
    (before,) = user_laps(engine.plan_jobs(load_recipe(tmp_path / "a" / "mine.yaml", DOMAIN), DOMAIN))
    shutil.move(tmp_path / "a", tmp_path / "b")
    recipe = load_recipe(tmp_path / "b" / "mine.yaml", DOMAIN)
    store = engine.open_store(DOMAIN, tmp_path / "store")
    plan = engine.make_plan(recipe, DOMAIN, store)
    (moved,) = user_laps([status.job for status in plan.statuses])
    assert moved.key == before.key and moved.inputs["brain_source"].path == str(tmp_path / "b" / "brains" / "mine.py")
    summary = run_plan(Plan(recipe, [status for status in plan.statuses if status.job is moved]), DOMAIN, store)
    assert [outcome.status for outcome in summary.outcomes] == ["ok"], summary
    assert store.result(moved.key)["value"]["brain"] == "mine"


@pytest.mark.slow   # a lap through the store and a report, ~13 s; test_pilotlab_drive_with_a_user_brain drives one
def test_a_user_brain_s_lap_runs_in_the_store_and_gets_its_report_row(tmp_path):
    result, reports = run_user_laps(tmp_path, timeout_s=4.0)
    assert result["strategy"] == "mine" and result["brain"] == "mine" and result["runs"][0]["termination"] == "timeout"
    assert result["completed_distance_m"] > 15 and result["off_road_events"] == 0
    readme = (reports / "README.md").read_text()
    row = next(line for line in readme.splitlines() if line.startswith("| reference · mine |"))
    assert "not run" not in row and "failed" not in row and "| 20.0 |" in row   # brain frequency, lockstep
    assert (reports / "trajectories" / "reference_mine_cpu_simple_circuit_cw.png").is_file()
    assert "trajectories/reference_mine_cpu_simple_circuit_cw.png" in readme


@pytest.mark.slow
def test_a_user_brain_completes_simple_circuit_through_the_recipe(tmp_path):
    result, reports = run_user_laps(tmp_path, timeout_s=None)
    assert result["lap_completed"] is True and result["position_deviation_mae_m"] < 0.5


def drive(tmp_path, monkeypatch, *timeout: str) -> dict:
    write_red_line(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["drive", "--brain", SPEC, "--circuit", "simple_circuit", "--timing", "lockstep",
                 *timeout, "--out", "run"]) == 0
    return json.loads((tmp_path / "run" / "result.json").read_text())


def test_pilotlab_drive_with_a_user_brain(tmp_path, monkeypatch):
    result = drive(tmp_path, monkeypatch, "--timeout", "5")
    assert result["brain"] == "RedLine" and result["completed_distance_m"] > 20
    assert (tmp_path / "run" / "trajectory.png").is_file()


@pytest.mark.slow
def test_pilotlab_drive_with_a_user_brain_completes_a_lap(tmp_path, monkeypatch):
    result = drive(tmp_path, monkeypatch)
    assert result["lap_completed"] is True and result["runs"][0]["termination"] == "lap_completed"


def test_pilotlab_drive_names_the_line_of_a_broken_brain(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "brains").mkdir()
    (tmp_path / "brains" / "bad.py").write_text("import numpy\n\nclass B:\n    def act(self, image):\n"
                                                "        return numpy.nope(image)\n")
    bad = ["drive", "--brain", "brains/bad.py:B", "--circuit", "simple_circuit", "--timeout", "1"]
    assert main([*bad, "--out", "run"]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and f"{tmp_path / 'brains' / 'bad.py'}:5: AttributeError" in error[0]
    (tmp_path / "brains" / "bad.py").write_text("class B:\n    def act(self, image)\n")
    assert main([*bad, "--out", "run2"]) == 2
    assert f"{tmp_path / 'brains' / 'bad.py'}:2: syntax error" in capsys.readouterr().err


def test_pilotlab_drive_with_a_brain_that_calls_exit_is_one_line_and_fails(tmp_path, monkeypatch, capsys):
    """Outside test: a brain raising SystemExit(0) ended `pilotlab drive` with code 0, nothing written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "brains").mkdir()
    (tmp_path / "brains" / "quits.py").write_text("class Quits:\n    def act(self, image):\n        raise SystemExit(0)\n")
    assert main(["drive", "--brain", "brains/quits.py:Quits", "--circuit", "simple_circuit", "--timeout", "1",
                 "--out", "run"]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "called exit(0)" in error[0]


def test_planning_reads_a_user_brain_but_never_runs_it(tmp_path):
    recipe = recipe_at(tmp_path)
    (tmp_path / "brains" / "mine.py").write_text("raise SystemExit('planning ran the brain')\n\n\nclass RedLine:\n"
                                                 "    def act(self, image):\n        return 1.0, 0.0\n")
    (lap,) = user_laps(engine.plan_jobs(load_recipe(recipe.file, DOMAIN), DOMAIN))
    assert lap.inputs["brain_source"].sha256 == source_hash(SPEC, tmp_path)
