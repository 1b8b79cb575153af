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
    assert "holds no result of the cells of recipe 'quickstart'" in error and "pilotlab run" in error
    assert not (tmp_path / "reports").exists()


def test_report_refuses_a_store_holding_only_a_recording_another_recipe_shares(tmp_path, monkeypatch, capsys):
    """outside test: one fresh shared recording let `report` write '0 ok, 10 not run yet' and exit 0."""
    from matrix.worker import execute_job
    monkeypatch.chdir(tmp_path)
    recipe, store = load_recipe(QUICKSTART, DOMAIN), Store(tmp_path / "store")
    test_set = next(s.job for s in make_plan(recipe, DOMAIN, store).statuses if s.job.name == "record test/simple_circuit cw")
    assert execute_job(str(store.root), test_set.spec(), DOMAIN.kind_modules, None)["status"] == "ok"
    assert main(["report", str(QUICKSTART), "--store", str(store.root)]) == 2
    assert "holds no result of the cells of recipe 'quickstart'" in capsys.readouterr().err
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


def test_the_report_stamp_changes_when_a_job_is_rerun_with_the_same_key(tmp_path):
    """`run --force offline` keeps keys and statuses; the report must still be rewritten."""
    from pilotlab.report.recipe import _stamp
    recipe, store = load_recipe(QUICKSTART, DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    offline = next(job for job in jobs if job.kind == "offline")

    def commit(latency: float) -> None:
        work = store.new_workdir(offline.key)
        store.commit(offline.key, work, offline.spec(), {"status": "ok", "value": {"latency_ms": latency}})
    commit(1.0)
    first = _stamp(recipe, jobs, store)
    assert _stamp(recipe, jobs, store) == first
    commit(0.9)
    assert _stamp(recipe, jobs, store) != first


def test_a_lap_is_marked_with_the_unstable_timing_it_replays(tmp_path):
    recipe, store = load_recipe(QUICKSTART, DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    lap = next(job for job in jobs if job.kind == "online" and "timing" in job.deps)
    timing = lap.deps["timing"]

    def commit(job, value: dict) -> None:
        store.commit(job.key, store.new_workdir(job.key), job.spec(), {"status": "ok", "value": value})
    commit(timing, {"latency_ms": 132.5, "unstable": {"latency_ms": "few calls ran undisturbed"}})
    commit(lap, {"lap_completed": False, "percentage_completed": 12.0, "mean_inference_ms": 136.0})
    row = next(r for r in build_report_data(recipe, jobs, store).rows if r.kind == "online" and r.status == "ok")
    assert row.unstable_reason("latency_ms") == (f"it replays the timing of {timing.name}, which stayed "
                                                 "disturbed (few calls ran undisturbed)")


def test_offline_timings_of_a_latency_file_profile_say_they_are_this_host_s(tmp_path):
    """Outside test: with `hardware: {jet: {latency_file: ...}}` the offline table said "jet ... baseline
    3.60 ms" and "Fastest on jet" from timings taken on the planning VM, while jet's laps replayed 50 ms."""
    (tmp_path / "jet.csv").write_text("strategy,latency_ms\nbaseline,50\n,30\n")
    text = QUICKSTART.read_text().replace("matrix:", "hardware:\n  jet: {latency_file: jet.csv}\nmatrix:")
    (tmp_path / "q.yaml").write_text(text.replace("hardware: [cpu]", "hardware: [jet]"))
    recipe, store = load_recipe(tmp_path / "q.yaml", DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    # the report's host is the one its timing jobs ran on (not the machine making the report)
    timing = next(job for job in jobs if job.kind == "timing")
    store.commit(timing.key, store.new_workdir(timing.key), timing.spec(),
                 {"status": "ok", "value": {"latency_ms": 3.6, "throughput_ips": 700.0,
                                            "host": {"cpu": "AMD EPYC", "cores": 2}}})
    offline = next(job for job in jobs if job.kind == "offline")
    store.commit(offline.key, store.new_workdir(offline.key), offline.spec(),
                 {"status": "ok", "value": {"latency_ms": 3.6, "throughput_ips": 700.0, "mse": 0.01,
                                            "host": {"cpu": "AMD EPYC", "cores": 2}}})
    row = next(r for r in build_report_data(recipe, jobs, store).rows if r.kind == "offline" and r.status == "ok")
    assert row.unstable_reason("latency_ms") == ("timed on this report's host (AMD EPYC, 2 cores), not on jet; "
                                                 "jet's laps replay its latency file (jet.csv)")


def test_the_reports_host_has_this_machines_os_only_when_the_timings_are_this_machines(tmp_path):
    """A timing job's host record (its fingerprint) has no OS; the report said `"os": ""` for this machine."""
    import platform

    from pilotlab.hardware import host_fingerprint
    recipe, store = load_recipe(QUICKSTART, DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    timing = next(job for job in jobs if job.kind == "timing")
    for host, os_name in ((host_fingerprint(), platform.platform(terse=True)),
                          ({**host_fingerprint(), "cpu": "Jetson Orin"}, "")):
        store.commit(timing.key, store.new_workdir(timing.key), timing.spec(),
                     {"status": "ok", "value": {"latency_ms": 1.0, "host": host}})
        data = build_report_data(recipe, jobs, store)
        assert (data.host.cpu, data.host.os) == (host["cpu"], os_name)
    assert platform.platform(terse=True)


def test_an_offline_row_shows_the_parameter_counts_of_the_network_it_evaluates(tmp_path):
    """Outside test: params, nonzero_params and sparsity were empty in every report (and results.csv):
    the optimize job has them, the offline row read only the offline job's result."""
    recipe, store = load_recipe(QUICKSTART, DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    offline = next(job for job in jobs if job.kind == "offline" and job.labels["strategy"] == "structured_prune_int8")
    optimize = offline.deps["artifact"]

    def commit(job, value: dict) -> None:
        store.commit(job.key, store.new_workdir(job.key), job.spec(), {"status": "ok", "value": value})
    commit(optimize, {"params": 832016, "nonzero_params": 832016, "params_before": 1595528, "size_mb": 0.82})
    commit(offline, {"mse": 0.0035, "size_mb": 0.82, "latency_ms": 0.19})
    row = next(r for r in build_report_data(recipe, jobs, store).rows if r.job_keys.get("offline") == offline.key)
    assert (row.get("params"), row.get("nonzero_params"), row.get("sparsity"), row.get("mse")) == (832016, 832016, None, 0.0035)


def test_a_test_set_the_network_was_trained_on_is_said_under_the_offline_table(tmp_path):
    """Outside test: `test:` the same recordings as `train:` was evaluated without a word (the offline jobs
    reuse the training frames jobs): the MSE was on training data."""
    from pilotlab.report.tables import build_tables
    text = QUICKSTART.read_text().replace("test:\n    record: {circuits: [simple_circuit], directions: [cw], laps: 0.5, seed: 2}",
                                          "test:\n    record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 1, "
                                          "noise: 0.1, seed: 1}")
    assert "noise: 0.1, seed: 1}\nmodels" in text
    (tmp_path / "leak.yaml").write_text(text)
    recipe, store = load_recipe(tmp_path / "leak.yaml", DOMAIN), Store(tmp_path / "store")
    jobs = [status.job for status in make_plan(recipe, DOMAIN, store).statuses]
    offline = next(job for job in jobs if job.kind == "offline" and job.labels["strategy"] == "baseline")
    store.commit(offline.key, store.new_workdir(offline.key), offline.spec(), {"status": "ok", "value": {"mse": 0.001}})
    data = build_report_data(recipe, jobs, store)
    row = next(r for r in data.rows if r.job_keys.get("offline") == offline.key)
    assert [name.split("/")[-1] for name in row.trained_on] == ["simple_circuit ccw", "simple_circuit cw"]
    (table,) = build_tables(data, "offline")
    assert any(f"pilotnet: the test set holds recordings it was trained on ({', '.join(row.trained_on)}): its MSE "
               "here is partly on training data" in note for note in table.notes)
    clean = load_recipe(QUICKSTART, DOMAIN)
    clean_jobs = [status.job for status in make_plan(clean, DOMAIN, store).statuses]
    assert all(not r.trained_on for r in build_report_data(clean, clean_jobs, store).rows)


def test_the_report_says_what_each_model_was_trained_on(tmp_path):
    """Outside test: two models trained on two datasets both read "trained here", nothing of their data."""
    from pilotlab.report.recipe import training_data
    recipe = load_recipe(QUICKSTART, DOMAIN)
    result = {"status": "ok", "value": {"trained": True, "recordings": 2, "train_frames": 1898, "val_frames": 476,
                                        "val_by": "block"}}
    assert training_data(recipe, "pilotnet", result) == (
        "trained on dataset 'train': 2 recording(s), 1,898 frames (476 more held out for validation, by block)")
    assert training_data(recipe, "pilotnet", {"status": "ok", "value": {"trained": False}}) is None
    assert training_data(recipe, "pilotnet", None) is None
