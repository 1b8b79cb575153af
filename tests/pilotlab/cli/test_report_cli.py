"""`pilotlab report` on a store without the recipe's results, and the rows of cells that never ran."""
from pathlib import Path

from matrix.engine import make_plan
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.cli import main
from pilotlab.domain import DOMAIN
from pilotlab.report.recipe import build_report_data

QUICKSTART = Path(__file__).resolve().parents[3] / "recipes" / "quickstart.yaml"


def test_report_refuses_a_store_without_any_result_and_writes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["report", str(QUICKSTART), "--store", str(tmp_path / "empty")]) == 2
    error = capsys.readouterr().err
    assert "holds no result of recipe 'quickstart'" in error and "pilotlab run" in error
    assert not (tmp_path / "reports").exists()


def test_cells_that_never_ran_are_not_run_yet_not_failed(tmp_path):
    recipe, store = load_recipe(QUICKSTART, DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    train = next(job for job in jobs if job.kind == "train")
    data = build_report_data(recipe, jobs, store)
    assert {(row.status, row.reason) for row in data.rows} == {("not_run", "not run yet")}
    store.record_failure(train.key, {"error": "RuntimeError: loss is nan"})
    data = build_report_data(recipe, jobs, store)
    assert {(row.status, row.reason) for row in data.rows if row.model == "pilotnet"} \
        == {("failed", "dependency failed: train pilotnet: RuntimeError: loss is nan")}
