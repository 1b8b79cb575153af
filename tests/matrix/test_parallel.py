"""Many jobs at once, timing jobs alone: -j N gives the results of -j 1, and no job runs beside an
exclusive (timing) one, locally and on Dask."""
import json
from pathlib import Path

import pytest

from matrix import engine
from matrix.runs import default_jobs
from matrix.recipe import load_recipe
from matrix.store import Store
from tests.matrix.toydomain import TOY

RECIPE = """\
name: toy
sources:
  a: {value: 2}
  b: {value: 3}
  c: {value: 5}
matrix:
  source: [a, b, c]
  power: [2, 3]
sleep: 0.3
measures: true
"""


def plan_of(tmp_path: Path, store: Store):
    path = tmp_path / "r.yaml"
    path.write_text(RECIPE)
    return engine.make_plan(load_recipe(path, TOY), TOY, store)


def result_files(store: Store) -> dict[str, object]:
    """Every job's result value and artifact files, by job name (what a report would read)."""
    files = {}
    for key in store.keys():
        name = store.spec(key)["name"]
        files[name] = store.result(key)["value"]
        for path in sorted((store.job_dir(key) / "artifacts").rglob("*")):
            files[f"{name}/{path.name}"] = path.read_bytes()
    return files


def intervals(store: Store) -> list[tuple[str, float, float, str, str]]:
    """(kind, start, end, job name, host) of each job's work, from the toy domain's intervals.log."""
    rows = (store.root / "cache" / "intervals.log").read_text().splitlines()
    return [(kind, float(start), float(end), store.spec(key)["name"], host)
            for kind, key, start, end, host in (row.split() for row in rows)]


def assert_timings_ran_alone(store: Store) -> None:
    runs = intervals(store)
    timings = [r for r in runs if r[0] == "measure"]
    assert len(timings) == 6
    for kind, start, end, name, _ in timings:
        beside = [other for other in runs if other[3] != name and other[1] < end and start < other[2]]
        assert not beside, f"{name} ran beside {beside}"


def test_many_jobs_at_once_give_the_same_result_files_as_one_at_a_time(tmp_path):
    one, many = Store(tmp_path / "one"), Store(tmp_path / "many")
    assert engine.run_plan(plan_of(tmp_path, one), TOY, one, jobs=1).counts() == {"ok": 16}
    summary = engine.run_plan(plan_of(tmp_path, many), TOY, many, jobs=4)
    assert summary.counts() == {"ok": 16}
    assert result_files(many) == result_files(one)
    assert sorted(many.keys()) == sorted(one.keys())
    assert_timings_ran_alone(many)
    # Other jobs did overlap: the run used the workers (a source and powers are free to run together).
    runs = [r for r in intervals(many) if r[0] == "power"]
    assert any(a[1] < b[2] and b[1] < a[2] for a in runs for b in runs if a is not b)


def test_on_dask_a_timing_job_runs_with_nothing_beside_it(tmp_path):
    distributed = pytest.importorskip("distributed")
    from matrix.dask_executor import run_dask
    one, store = Store(tmp_path / "one"), Store(tmp_path / "dask")
    engine.run_plan(plan_of(tmp_path, one), TOY, one, jobs=1)
    with distributed.LocalCluster(n_workers=3, threads_per_worker=1, processes=True, dashboard_address=None) \
            as cluster, distributed.Client(cluster) as client:
        summary = run_dask(plan_of(tmp_path, store).statuses, store, client, kind_modules=TOY.kind_modules)
    assert summary.counts() == {"ok": 16}, summary.outcomes
    assert result_files(store) == result_files(one)
    assert_timings_ran_alone(store)


def test_by_default_as_many_jobs_as_cores(tmp_path, capsys):
    from matrix.cli import main
    path = tmp_path / "r.yaml"
    path.write_text(RECIPE.replace("sleep: 0.3", "sleep: 0.0"))
    assert main(["run", str(path), "--store", str(tmp_path / "s")], TOY, prog="toy") == 0
    assert f"on {default_jobs()} worker" in capsys.readouterr().out
    assert json.loads((tmp_path / "s" / "stats.json").read_text())  # the run went through
