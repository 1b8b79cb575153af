"""The world-shift section: tables, summary and plot from rows evaluated in BM worlds."""
from __future__ import annotations

from pilotlab.report.data import ReportData
from pilotlab.report.plots import save_plots
from pilotlab.report.worlds import shift_summary, world_tables


def rows(strategy: str, world: str, mse: float, deviation: float, completed: bool) -> list[dict]:
    base = {"model": "pilotnet", "strategy": strategy, "hardware": "cpu", "world": world}
    return [{**base, "kind": "offline", "test_set": f"test in {world}", "mse": mse},
            {**base, "kind": "online", "circuit": world, "direction": "cw", "lap_completed": completed,
             "percentage_completed": 100.0 if completed else 40.0, "bm_position_deviation_mae": deviation,
             "latency_tolerance_ms": 120.0 if completed else None}]


def data(int8_mse_shifted: float = 0.06, int8_completes: bool = True) -> ReportData:
    table = (rows("baseline", "simple_circuit", 0.02, 2.0, True) + rows("baseline", "white_line", 0.05, 3.0, True)
             + rows("int8", "simple_circuit", 0.02, 2.0, True) + rows("int8", "white_line", int8_mse_shifted, 3.0,
                                                                     int8_completes))
    return ReportData.from_dict({"recipe_name": "w", "date": "2026-11-25T10:00:00", "rows": table,
                                 "training_worlds": {"pilotnet": ["simple_circuit"]}})


def test_table_puts_each_world_beside_the_training_world():
    (table,) = world_tables(data())
    cells = {(row.method, row.cells[0].text): [cell.text for cell in row.cells] for row in table.rows}
    assert [key for key in cells][:2] == [("baseline", "simple_circuit"), ("baseline", "white_line")]
    assert cells["baseline", "simple_circuit"][5] == "training world"
    assert cells["baseline", "white_line"][5] == "2.50×" and cells["baseline", "white_line"][6] == "1.50×"
    assert cells["int8", "white_line"][5] == "3.00×"


def test_summary_says_who_lost_more_than_the_baseline():
    worse = shift_summary(data(int8_mse_shifted=0.06))
    assert "int8 lost more than the baseline" in worse[-1]
    same = shift_summary(data(int8_mse_shifted=0.05))
    assert "no optimized network lost more" in same[-1]
    lost = shift_summary(data(int8_mse_shifted=0.05, int8_completes=False))
    assert "int8 lost more" in lost[-1] and "0/1 laps completed" in lost[1]
    assert lost[0].startswith("pilotnet/baseline: lap completed in the training world;")


def test_no_verdict_when_the_baseline_loses_its_lap_in_its_own_world_and_no_ratio_to_a_lost_lap():
    table = (rows("baseline", "simple_circuit", 0.02, 900.0, False) + rows("baseline", "white_line", 0.05, 3.0, True)
             + rows("int8", "simple_circuit", 0.02, 2.0, True) + rows("int8", "white_line", 0.02, 850.0, False))
    lost = ReportData.from_dict({"recipe_name": "w", "date": "2026-11-25T10:00:00", "rows": table,
                                 "training_worlds": {"pilotnet": ["simple_circuit"]}})
    assert shift_summary(lost)[-1] == ("pilotnet: no conclusion on the world shift: the baseline lost its lap in "
                                       "its training world already")
    (tables,) = world_tables(lost)
    cells = {(row.method, row.cells[0].text): row.cells[6].text for row in tables.rows}
    assert cells["baseline", "white_line"] == cells["int8", "white_line"] == "lap lost"   # at home, or here


def test_no_ratio_and_no_verdict_without_the_training_world_in_the_matrix():
    """Outside test: trained in simple_circuit, evaluated in white_line alone, the summary said "offline MSE
    1.00× its training-world MSE" (each world divided by itself) and that the baseline "drove no lap"."""
    table = rows("baseline", "white_line", 0.05, 3.0, True) + rows("int8", "white_line", 0.06, 3.0, True)
    away = ReportData.from_dict({"recipe_name": "w", "date": "2026-11-25T10:00:00", "rows": table,
                                 "training_worlds": {"pilotnet": ["simple_circuit"]}})
    lines = shift_summary(away)
    assert lines[0] == ("pilotnet/baseline: not evaluated in the training world (add it to matrix.world); 1/1 laps "
                        "completed in the shifted worlds, offline MSE not measured in both")
    assert lines[-1] == ("pilotnet: no conclusion on the world shift: the baseline was not driven in its training "
                         "world (add it to matrix.world)")
    from pilotlab.report.plots import draw_world_shift
    assert draw_world_shift(away) is None


def test_the_plot_is_drawn(tmp_path):
    plots = save_plots(data(int8_completes=False), tmp_path)
    assert "world_shift" in plots and plots["world_shift"][0].stat().st_size > 5000


def test_no_section_without_a_shifted_world():
    only = ReportData.from_dict({"recipe_name": "w", "date": "2026-11-25T10:00:00",
                                 "rows": rows("baseline", "simple_circuit", 0.02, 2.0, True),
                                 "training_worlds": {"pilotnet": ["simple_circuit"]}})
    assert world_tables(only) == [] and shift_summary(only) == []


def test_the_plot_draws_no_deviation_ratio_to_a_lost_lap():
    """Outside test: the table refused a lost lap's deviation ratio ("says nothing"), the plot drew it as a
    bar (0.44×, reading better than the training world): now a cross marks it, as the table's "lap lost", at
    the top of the panel (at 1.0 it read "as in the training world")."""
    from pilotlab.report.plots import LOST_AT, draw_world_shift
    figure = draw_world_shift(data(int8_completes=False))
    mse_axis, deviation_axis = figure.axes[:2]
    assert len(mse_axis.patches) == 4                              # every MSE ratio, the lost lap's hatched
    assert len(deviation_axis.patches) == 3                        # not the lost lap's deviation ratio
    crosses = [line for line in deviation_axis.get_lines() if line.get_marker() == "x"]
    assert len(crosses) == 1 and list(crosses[0].get_ydata()) == [LOST_AT]
    assert crosses[0].get_transform() == deviation_axis.get_xaxis_transform()   # y in the panel's height


def test_the_simulation_tables_of_laps_in_a_world_are_headed_by_the_world():
    """Outside test: "### cpu · circuit simple_circuit_white_line cw" headed the laps in a world."""
    from pilotlab.report.tables import build_tables
    titles = [table.title for table in build_tables(data(), "online")]
    assert titles == ["cpu · world simple_circuit cw", "cpu · world white_line cw"]
