from pilotlab.report import ReportData
from pilotlab.report.plots import draw_closed_loop, draw_pareto, draw_ratios, draw_training, pareto_front, save_plots
from tests.pilotlab.report.toy import offline_row, small_dict


def test_pareto_front_keeps_the_points_nothing_beats():
    points = [(2.2, 0.079), (2.1, 0.073), (2.15, 0.071), (2.7, 0.067), (3.2, 0.078), (2.7, 0.070)]
    assert pareto_front(points) == [(2.1, 0.073), (2.15, 0.071), (2.7, 0.067)]
    assert pareto_front([]) == []


def test_cells_without_the_needed_values_draw_nothing():
    rows = [offline_row("baseline", size_mb=6.1, mse=0.07),                    # no latency: not on the Pareto plot
            offline_row("qat", status="failed", reason="diverged")]
    data = ReportData.from_dict(small_dict(rows))
    assert draw_pareto(data) is None and draw_closed_loop(data) is None and draw_training(data) is None
    assert draw_ratios(data) is not None                                          # size ratio exists


def test_plots_show_every_strategy_and_hardware(study):
    figure = draw_pareto(study)
    axes = [ax for ax in figure.axes if ax.get_visible()]
    assert [ax.get_title() for ax in axes] == ["cpu1", "cpu4"]
    legend = [t.get_text() for t in figure.legends[0].get_texts()]
    assert legend[:7] == list(study.strategies()) and "Pareto front (stable timings)" in legend and "6.12 MB" in legend
    ratios = draw_ratios(study)
    labels = [t.get_text() for t in ratios.axes[1].texts]
    assert "not applicable" in labels and "failed" in labels                     # shown as such, not as 0
    titles = [ax.get_title() for ax in draw_closed_loop(study).axes if ax.get_visible()]
    assert titles == ["simple_circuit cw · cpu1", "montreal cw · cpu1"]


def test_no_speed_up_bar_is_drawn_from_an_unstable_timing():
    rows = [offline_row("baseline", size_mb=6.1, mse=0.07, latency_ms=2.3, latency_p10_ms=2.2, latency_p90_ms=9.0,
                        unstable={"latency_ms": "only 4 of 24 calls ran with no thread of this process waiting"}),
            offline_row("static_quant", size_mb=1.6, mse=0.07, latency_ms=0.4)]
    data = ReportData.from_dict(small_dict(rows))
    speed = draw_ratios(data).axes[1]
    assert [t.get_text() for t in speed.texts] == ["⚠ unstable timing", "⚠ unstable timing"] and not speed.patches
    figure = draw_pareto(data)
    legend = [t.get_text() for t in figure.legends[0].get_texts()]
    assert "⚠ unstable timing" in legend
    # outside test: the front ran through the unstable point, and a one-point front was a hollow ring, the
    # legend's unstable marker; it is the stable points' front, a lone point squared
    (front,) = [line for line in figure.axes[0].get_lines() if line.get_linestyle() == "--"]
    assert list(front.get_xdata()) == [0.4] and front.get_marker() == "s"
    rows[1]["unstable"] = rows[0]["unstable"]
    legend = [t.get_text() for t in draw_pareto(ReportData.from_dict(small_dict(rows))).legends[0].get_texts()]
    assert not any("Pareto" in text for text in legend)          # no front drawn: none in the legend


def test_a_name_the_font_cannot_draw_warns_nothing(tmp_path):
    import warnings
    rows = [{"model": "モデル", "strategy": strategy, "hardware": "cpu", "kind": "offline", "test_set": "t",
             "mse": mse, "latency_ms": ms, "size_mb": 1.0} for strategy, mse, ms in (("baseline", 0.1, 1.0),
                                                                                    ("int8", 0.2, 0.5))]
    data = ReportData.from_dict({"recipe_name": "w", "date": "2026-11-25T10:00:00", "rows": rows})
    with warnings.catch_warnings():
        warnings.simplefilter("error")      # the glyph warnings were printed without --verbose
        assert set(save_plots(data, tmp_path)) == {"pareto", "ratios"}


def test_the_training_curves_say_which_precision_trained_the_model():
    history = [{"epoch": e, "train_loss": 0.2 / e, "val_loss": 0.25 / e, "precision": "bf16"} for e in (1, 2)]
    data = ReportData.from_dict(small_dict([offline_row("baseline", mse=0.07)], histories={"pilotnet": history}))
    assert [ax.get_title() for ax in draw_training(data).axes if ax.get_visible()] == ["pilotnet (bf16 mixed precision)"]
    older = [{k: v for k, v in point.items() if k != "precision"} for point in history]   # results before the setting
    data = ReportData.from_dict(small_dict([offline_row("baseline", mse=0.07)], histories={"pilotnet": older}))
    assert [ax.get_title() for ax in draw_training(data).axes if ax.get_visible()] == ["pilotnet"]
