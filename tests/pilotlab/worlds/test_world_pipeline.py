"""Slow: a recipe over the test-written world end to end (`pilotlab run` as a user runs it): recorded in one
world, evaluated offline and driven in two, a report with its World shift section and plot, and a plan
afterwards with every job fresh."""
from __future__ import annotations

import json

import pytest
from tests.child import run_pilotlab

RECIPE = """
name: tiny_worlds
worlds: {{assets: {assets}}}
datasets:
  train: {{record: {{worlds: [oval], laps: 0.3, camera: {{width: 160, height: 120}}}}}}
  test: {{record: {{worlds: [oval], laps: 0.1, seed: 2, camera: {{width: 160, height: 120}}}}}}
models:
  pilotnet: {{arch: pilotnet, epochs: 1, val_fraction: 0}}
online: {{timeout_s: 3, references: [], camera: {{width: 160, height: 120}}}}
matrix:
  model: [pilotnet]
  strategy: [baseline]          # one strategy: the timing jobs are what this test spends most on
  world: [oval, oval_no_sun]
"""


pilotlab = run_pilotlab


@pytest.mark.slow
def test_a_recipe_over_worlds_runs_reports_and_stays_fresh(tmp_path, oval_assets):
    (tmp_path / "worlds.yaml").write_text(RECIPE.format(assets=oval_assets))
    run = pilotlab("run", "worlds.yaml", "--store", "store", cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    report = tmp_path / "reports" / "tiny_worlds"
    readme = (report / "README.md").read_text()
    assert "## World shift" in readme and "| baseline | oval_no_sun |" in readme
    assert (report / "plots" / "world_shift.png").is_file()
    rows = json.loads((report / "results.json").read_text())["rows"]
    assert {row["world"] for row in rows} == {"oval", "oval_no_sun"}
    offline = {row["world"]: row for row in rows if row["kind"] == "offline"}
    assert offline["oval"]["latency_ms"] == offline["oval_no_sun"]["latency_ms"]   # timed once
    plan = pilotlab("plan", "worlds.yaml", "--store", "store", "--json", cwd=tmp_path)
    assert plan.returncode == 0, plan.stderr
    statuses = {job["status"] for job in json.loads(plan.stdout)}
    assert statuses == {"fresh"}, plan.stdout[:2000]
