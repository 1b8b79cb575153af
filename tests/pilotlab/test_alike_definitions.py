"""Names with one definition (models, strategies) are planned once (matrix.grid): a grid of identical
entries makes the jobs of one entry, and the plan and the report still name every cell's names."""
from pathlib import Path

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.domain import DOMAIN
from pilotlab.report.recipe import build_report_data


def recipe_text(models: list[str], strategies: list[str], latency_file: str | None = None) -> str:
    lines = ["name: alike", "datasets:", "  train: {record: {circuits: [simple_circuit], laps: 0.2}}",
             "  test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 3}}", "models:"]
    lines += [f"  {name}: {{arch: pilotnet, epochs: 1}}" for name in models]
    lines += ["strategies:"] + [f"  {name}: {{use: local_prune, conv: 0.3}}" for name in strategies]
    if latency_file:
        lines += ["hardware:", f"  board: {{threads: 1, latency_file: {latency_file}}}"]
    lines += ["matrix:", f"  model: [{', '.join(models)}]", f"  strategy: [{', '.join(strategies)}, baseline]",
              f"  hardware: [cpu, {'board' if latency_file else 'cpu1'}]", "  circuit: [simple_circuit, montreal]"]
    return "\n".join(lines) + "\n"


def plan(tmp_path: Path, text: str):
    path = tmp_path / "recipe.yaml"
    path.write_text(text)
    recipe = load_recipe(path, DOMAIN)
    return recipe, engine.plan_jobs(recipe, DOMAIN)


def test_a_grid_of_identical_entries_makes_the_jobs_of_one(tmp_path):
    models, strategies = [f"m{i}" for i in range(100)], [f"s{i}" for i in range(40)]
    recipe, jobs = plan(tmp_path, recipe_text(models, strategies))
    _, one = plan(tmp_path, recipe_text(["m0"], ["s0"]))
    assert recipe.grid.count() == 100 * 41 * 2 * 2 and len(recipe.combinations) == 2 * 2 * 2
    assert [(job.name, job.key) for job in jobs] == [(job.name, job.key) for job in one]
    assert len(jobs) == 2 + 2 + 1 + 1 + 2 + 2 * 2 + 2 * 2 + 2 * 2 * 2 + 2 * 2   # records, frames, train,
    #   s0's prepared network (local_prune), optimize, timing, offline, laps, explicit + expert laps (on the
    #   first CPU profile: replayed, they do not depend on it)
    assert recipe.grid.same_as("model", "m0") == models and recipe.grid.same_as("strategy", "s0") == strategies
    data = build_report_data(recipe, jobs, Store(tmp_path / "store"))
    assert data.same_as == {"m0": tuple(models[1:]), "s0": tuple(strategies[1:])}


def test_names_a_latency_file_tells_apart_are_planned_each(tmp_path):
    # a device's latency file is looked up by model and strategy name: each name is its own lap
    (tmp_path / "board.csv").write_text("model,strategy,latency_ms\n,,25\n")
    recipe, jobs = plan(tmp_path, recipe_text(["m0", "m1"], ["s0", "s1"], latency_file="board.csv"))
    assert len(recipe.combinations) == recipe.grid.count() == 2 * 3 * 2 * 2
    laps = [job for job in jobs if job.kind == "online" and job.labels["hardware"] == "board"
            and job.params["brain"] == "network"]
    assert len(laps) == 2 * 3 * 2 and {lap.params["latency_for"]["model"] for lap in laps} == {"m0", "m1"}


def test_strategies_that_differ_only_by_written_defaults_are_one_entry(tmp_path):
    # s0 writes the default conv out, s1 leaves it out: one definition, planned once
    text = recipe_text(["m0"], ["s0", "s1"]).replace("s1: {use: local_prune, conv: 0.3}", "s1: {use: local_prune}")
    assert "s1: {use: local_prune}" in text
    recipe, jobs = plan(tmp_path, text)
    assert recipe.grid.same_as("strategy", "s0") == ["s0", "s1"]
    assert len([job for job in jobs if job.kind == "optimize"]) == 2   # s0 (for both) and baseline
