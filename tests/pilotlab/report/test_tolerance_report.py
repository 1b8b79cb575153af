"""The latency tolerance in the report: a column of the simulation table, a plot, the CSV."""
from pilotlab.report.data import ReportData
from pilotlab.report.plots import draw_latency_tolerance
from pilotlab.report.tables import TOLERANCE_HEADER, build_tables
from pilotlab.report.writer import results_csv
from tests.pilotlab.report.toy import online_row, small_dict


def searched(strategy, tolerance, laps, at_least=False):
    row = online_row(strategy, lap_completed=laps[0][1], position_deviation_mae_m=laps[0][2])
    if tolerance is not None:
        row["latency_tolerance_ms"] = tolerance
    points = [{"injected_ms": ms, "lap_completed": done, "position_deviation_mae_m": deviation,
               "termination": "lap_completed" if done else "off_road"} for ms, done, deviation in laps]
    return {**row, "tolerance": points, "tolerance_at_least": at_least}


def tolerance_data():
    return ReportData.from_dict(small_dict([
        searched("baseline", 140.0, [(0.0, True, 0.2), (100.0, True, 0.4), (140.0, True, 0.6), (145.0, False, 1.9),
                                     (200.0, False, 2.2)]),
        searched("dynamic_quant", 1000.0, [(0.0, True, 0.1), (200.0, True, 0.3), (1000.0, True, 0.9)], at_least=True),
        searched("qat", None, [(0.0, False, 2.5)]),
        online_row("local_prune", lap_completed=True, position_deviation_mae_m=0.3)]))


def test_the_simulation_table_shows_the_tolerance_where_a_lap_searched_it():
    table = build_tables(tolerance_data(), "online")[0]
    assert table.headers[-1] == TOLERANCE_HEADER
    cells = {row.method: row.cells[-1].text for row in table.rows}
    assert cells == {"baseline": "140", "dynamic_quant": "≥ 1000", "qat": "lost at 0", "local_prune": "—"}


def test_no_tolerance_column_without_a_search():
    data = ReportData.from_dict(small_dict([online_row("baseline", lap_completed=True)]))
    assert TOLERANCE_HEADER not in build_tables(data, "online")[0].headers


def test_the_plot_draws_a_line_per_strategy_and_marks_lost_laps():
    figure = draw_latency_tolerance(tolerance_data())
    ax = figure.axes[0]
    lines = {tuple(line.get_xdata()) for line in ax.get_lines()}
    assert (0.0, 100.0, 140.0) in lines and (0.0, 200.0, 1000.0) in lines
    lost = sorted(tuple(point) for collection in ax.collections for point in collection.get_offsets())
    assert lost == [(0.0, 2.5), (145.0, 1.9), (200.0, 2.2)]


def test_the_csv_has_the_tolerance():
    text = results_csv(tolerance_data(), {})
    header = text.splitlines()[0].split(",")
    assert "latency_tolerance_ms" in header and "bm_position_deviation_mae" in header


def test_behaviormetrics_figures_are_columns_of_their_own_where_laps_have_them():
    rows = [online_row("baseline", lap_completed=True, bm_position_deviation_mae=7.406, bm_percentage_completed=101.3),
            online_row("qat", lap_completed=True)]
    table = build_tables(ReportData.from_dict(small_dict(rows)), "online")[0]
    assert table.headers[-2:] == ("BM deviation MAE (1000^d)", "BM completed (%)")
    assert [cell.text for cell in table.rows[0].cells[-2:]] == ["7.41", "101"]
    assert [cell.text for cell in table.rows[1].cells[-2:]] == ["—", "—"]


def test_a_simulation_table_says_where_its_replayed_latencies_came_from():
    source = "timing job, scaled ×56.4 so that baseline takes 124 ms"
    rows = [online_row("baseline", lap_completed=True) | {"latency_source": source},
            online_row("qat", lap_completed=True) | {"latency_source": source},
            online_row("expert", lap_completed=True) | {"latency_source": "none: a reference brain is charged only "
                                                                          "the injected latency"}]
    table = build_tables(ReportData.from_dict(small_dict(rows)), "online")[0]
    assert table.notes == (f"Latencies replayed from the {source}.",)


def test_the_legend_says_what_the_tolerance_column_is(tmp_path):
    """Outside test: the column was not explained (it is latency added to the lap's own, not the total)."""
    from pilotlab.report.writer import write_report
    write_report(tolerance_data(), tmp_path)
    for page in ("README.md", "index.html"):
        assert "Latency tolerance: the latency added to the lap's own" in (tmp_path / page).read_text()
    write_report(ReportData.from_dict(small_dict([online_row("baseline", lap_completed=True)])), tmp_path / "none")
    assert "Latency tolerance: the latency added" not in (tmp_path / "none" / "README.md").read_text()


def test_the_host_stalls_a_lap_replayed_unscaled_are_named_by_row():
    """Outside test: the study's tables ended with one note per stall count ("... (2 host stalls replayed
    unscaled)", five of them), none saying which rows they were."""
    source = "timing job, scaled ×119 so that baseline takes 124 ms"
    rows = [online_row("baseline", lap_completed=True) | {"latency_source": source},
            online_row("qat", lap_completed=True) | {"latency_source": source + " (2 host stalls replayed unscaled)"},
            online_row("local_prune", lap_completed=True) | {"latency_source": source + " (1 host stall replayed unscaled)"}]
    notes = build_tables(ReportData.from_dict(small_dict(rows)), "online")[0].notes
    assert notes[0] == f"Latencies replayed from the {source}."
    assert len(notes) == 2 and notes[1].startswith("Host stalls replayed unscaled")
    assert notes[1].endswith(": qat 2, local_prune 1.")
