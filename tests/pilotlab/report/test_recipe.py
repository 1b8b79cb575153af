"""Report rows from finished jobs (`pilotlab.report.recipe.row_from_result`): a real online job that
drives a lap from two start points gives a row whose cells show the mean with its spread."""
import pilotlab.jobs.online  # noqa: F401  (registers the kind)
from matrix.kinds import KINDS
from pilotlab.report import ReportData
from pilotlab.report.recipe import row_from_result
from pilotlab.report.tables import build_tables
from tests.pilotlab.jobs.context import context
from tests.pilotlab.report.toy import small_dict

IDENTITY = {"model": "expert", "strategy": "expert", "hardware": "cpu1", "kind": "online"}


def test_an_online_job_repeated_from_two_starts_gives_a_row_with_its_spread(tmp_path, stadium_csv):
    params = {"circuit": stadium_csv, "brain": "expert", "repetitions": 2, "camera_frames": 0,
              "camera": {"width": 64, "height": 48}, "hardware": {"name": "cpu1", "threads": 1}}
    ctx = context(tmp_path, "online", "online-expert", params)
    result = KINDS.get("online").handler(ctx)
    row = {**IDENTITY, "circuit": "stadium", **row_from_result({"status": "ok", "value": result}, ctx.out)}
    assert row["spread"]["lap_completed"] == {"completed": 2, "runs": 2}
    assert row["trajectory"] == str(ctx.out / "trajectory.png")
    [table] = build_tables(ReportData.from_dict(small_dict([row])), "online")
    lap, speed, deviation = (cell.text for cell in table.rows[0].cells[:3])
    speeds = [run["average_speed"] for run in result["runs"]]
    assert lap.startswith("✓ 2/2, ") and lap.endswith(" s") and " ± " in lap
    assert speed.startswith(f"{result['average_speed']:.2f} ± ") and min(speeds) < max(speeds)
    assert " ± " in deviation


def test_a_job_that_did_not_apply_gives_its_reason_and_no_numbers(tmp_path):
    row = row_from_result({"status": "not_applicable", "reason": "no GPU here"}, tmp_path)
    assert row == {"status": "not_applicable", "reason": "no GPU here"}


def test_a_cell_not_run_whose_optimize_job_did_not_apply_says_why_not_not_run_yet(tmp_path):
    """Outside test: a run that stopped at another failure left the cells of a strategy whose optimize job was
    not applicable as "not run yet" (when run, they are not applicable with its reason)."""
    from types import SimpleNamespace
    from matrix.jobs import Job
    from pilotlab.report.recipe import _row
    optimize = Job("optimize", "optimize m/stem5", {"strategy": "structured_prune", "options": {}})
    offline = Job("offline", "offline m/stem5 on cpu", {}, deps={"artifact": optimize},
                  labels={"model": "m", "strategy": "stem5", "hardware": "cpu", "test_set": "test"})
    results = {optimize.key: {"status": "not_applicable", "reason": "subsample_stem 5 needs a network whose ..."}}
    store = SimpleNamespace(result=results.get, failure=lambda key: None)
    row = _row(offline, store)
    assert row["status"] == "not_applicable" and row["reason"] == "subsample_stem 5 needs a network whose ..."
    store.result = {}.get
    assert (_row(offline, store)["status"], _row(offline, store)["reason"]) == ("not_run", "not run yet")


def test_the_report_names_the_host_that_timed_a_profile_of_another_machine():
    """Outside test K8: a jetson profile (worker_resource) timed on the Dask worker `jetsonbox` was reported
    under the planning host's line only; the host line names where each such profile was timed."""
    from types import SimpleNamespace
    from pilotlab.report.recipe import _host
    here = {"cpu": "AMD EPYC", "cores": 2, "gpu": None}
    values = {"t1": {"host": here, "hardware": {"name": "cpu1", "device": "cpu", "threads": 1}, "hostname": "vm"},
              "t2": {"host": {"cpu": "ARMv8 Processor rev 1 (v8l)", "cores": 8, "gpu": None}, "hostname": "jetsonbox",
                     "hardware": {"name": "jetson", "device": "cpu", "threads": 4, "worker_resource": "JETSON"}}}
    jobs = [SimpleNamespace(kind="timing", key=key) for key in ("t2", "t1")]
    host = _host(jobs, SimpleNamespace(result=lambda key: {"value": values[key]}))
    assert host.cpu == "AMD EPYC" and host.elsewhere == {"jetson": "jetsonbox (ARMv8 Processor rev 1 (v8l), 8 cores)"}
    assert host.describe() == ("AMD EPYC, 2 cores; GPU: none; jetson timed on jetsonbox (ARMv8 Processor rev 1 (v8l), "
                               "8 cores)")
