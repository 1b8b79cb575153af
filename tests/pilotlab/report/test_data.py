import math

import pytest

from pilotlab.report import Host, ReportData, ReportDataError, package_versions, pick_metrics, pick_spread
from tests.pilotlab.report.toy import offline_row, online_row, repeated_rows, small_dict


def test_metrics_may_be_flat_or_nested_and_unmeasured_ones_are_absent():
    flat = ReportData.from_dict(small_dict([offline_row(size_mb=6.1, mse=0.07, latency_ms=None)]))
    nested = ReportData.from_dict(small_dict([offline_row(metrics={"size_mb": 6.1, "mse": 0.07,
                                                                   "latency_ms": math.nan})]))
    assert flat.rows[0].metrics == nested.rows[0].metrics == {"size_mb": 6.1, "mse": 0.07}
    assert flat.rows[0].get("latency_ms") is None


def test_booleans_stay_booleans():
    row = {"model": "pilotnet", "strategy": "baseline", "hardware": "cpu1", "kind": "online",
           "circuit": "montreal", "lap_completed": True, "off_road_events": 2}
    data = ReportData.from_dict(small_dict([row]))
    assert data.rows[0].get("lap_completed") is True
    assert data.rows[0].get("off_road_events") == 2 and not isinstance(data.rows[0].get("off_road_events"), bool)


def test_an_unknown_metric_names_the_row_and_the_closest_known_name():
    with pytest.raises(ReportDataError) as error:
        ReportData.from_dict(small_dict([offline_row(), offline_row("qat", latncy_ms=2.0)]))
    message = str(error.value)
    assert "rows.1" in message and "pilotnet/qat/cpu1/offline" in message
    assert "'latncy_ms'" in message and "did you mean 'latency_ms'" in message


def test_a_cell_that_did_not_run_needs_a_reason_and_shows_no_values():
    with pytest.raises(ReportDataError, match="needs a one-line 'reason'"):
        ReportData.from_dict(small_dict([offline_row(status="failed")]))
    data = ReportData.from_dict(small_dict([offline_row(status="failed", reason="boom\n  at line 3", mse=0.5)]))
    assert data.rows[0].reason == "boom at line 3"
    assert data.rows[0].get("mse") is None            # a failed cell's partial numbers are not shown


def test_unknown_status_and_kind_are_rejected():
    with pytest.raises(ReportDataError, match="status"):
        ReportData.from_dict(small_dict([offline_row(status="skipped", reason="x")]))
    with pytest.raises(ReportDataError, match="kind"):
        ReportData.from_dict(small_dict([{**offline_row(), "kind": "benchmark"}]))


def test_axes_keep_recipe_order_with_the_baseline_first():
    rows = [offline_row("qat"), offline_row("baseline"), offline_row("qat", hardware="cpu4"),
            {**offline_row("local_prune"), "model": "tiny"}]
    data = ReportData.from_dict(small_dict(rows))
    assert data.strategies() == ["baseline", "qat", "local_prune"]
    assert data.hardware() == ["cpu1", "cpu4"] and data.models() == ["pilotnet", "tiny"]


def test_flat_row_has_every_metric_column_with_none_when_unmeasured():
    data = ReportData.from_dict(small_dict([offline_row(mse=0.07)]))
    flat = data.rows[0].flat()
    assert flat["mse"] == 0.07 and flat["latency_ms"] is None and flat["average_speed"] is None
    assert flat["status"] == "ok" and flat["test_set"] == "simple_circuit"
    assert flat["latency_tolerance_searched"] is None and list(flat)[-1] == "latency_tolerance_searched"


def test_a_lap_lost_at_once_and_a_lap_not_searched_are_told_apart_in_the_results():
    """Outside test: both left latency_tolerance_ms empty in results.csv, with nothing else to tell them apart."""
    lost = {**online_row(lap_completed=False), "tolerance": [{"injected_ms": 0.0, "lap_completed": False}]}
    data = ReportData.from_dict(small_dict([lost, online_row("qat")]))
    assert [row.flat()["latency_tolerance_searched"] for row in data.rows] == [True, False]
    assert all(row.flat()["latency_tolerance_ms"] is None for row in data.rows)


def test_host_and_versions_describe_this_machine():
    host = Host.detect()
    assert host.cpu and host.cores and host.cores >= 1
    assert "GPU" in host.describe()
    versions = package_versions()
    assert versions["torch"].startswith("2.") and "python" in versions and "no-such-package" not in versions


def test_pick_metrics_keeps_only_metric_names_of_a_job_result():
    result = {"mse": 0.07, "latency_ms": 2.0, "artifact": "model.pt", "history": [1, 2]}
    assert pick_metrics(result) == {"mse": 0.07, "latency_ms": 2.0}
    row = ReportData.from_dict(small_dict([offline_row(**pick_metrics(result))])).rows[0]
    assert row.metrics == {"mse": 0.07, "latency_ms": 2.0}


def test_a_repeated_lap_carries_its_spread_and_flattens_it_into_columns():
    repeated, _, single = ReportData.from_dict(small_dict(repeated_rows())).rows
    assert repeated.repetitions == 3 and repeated.spread_of("average_speed").std == 0.123
    flat = repeated.flat()
    assert (flat["repetitions"], flat["repetitions_completed"]) == (3, 3)
    assert (flat["average_speed_std"], flat["average_speed_min"], flat["average_speed_max"]) == (0.123, 8.81, 9.05)
    assert single.repetitions == 1 and single.spread_of("average_speed") is None     # one run: no spread
    assert single.flat()["repetitions_completed"] == 1 and "average_speed_std" not in single.flat()
    data = ReportData.from_dict(small_dict(repeated_rows()))
    assert data.spread_columns()[:5] == ["repetitions", "repetitions_completed", "percentage_completed_std",
                                         "percentage_completed_min", "percentage_completed_max"]
    assert "lap_completed_std" not in data.spread_columns()


def test_a_spread_of_an_unknown_metric_is_an_error_and_a_failed_row_shows_none():
    row = {**repeated_rows()[0], "spread": {"avg_speed": {"std": 0.1, "runs": 3}}}
    with pytest.raises(ReportDataError, match="spread of unknown metric 'avg_speed'.*did you mean 'average_speed'"):
        ReportData.from_dict(small_dict([row]))
    failed = ReportData.from_dict(small_dict([{**repeated_rows()[0], "status": "failed", "reason": "crash"}])).rows[0]
    assert failed.spread_of("average_speed") is None and failed.repetitions is None


def test_pick_spread_keeps_the_spread_of_known_metrics():
    result = {"average_speed": 8.9, "spread": {"average_speed": {"std": 0.1, "min": 8.8, "max": 9.0, "runs": 2},
                                               "speed_of_light": {"std": 0.0, "runs": 2}}}
    assert pick_spread(result) == {"average_speed": {"std": 0.1, "min": 8.8, "max": 9.0, "runs": 2}}
    assert pick_spread({"mse": 0.07}) == {}
