"""The run's display: time left labelled and smoothed, long names cut, and a status line at a steady
interval when the output is not a terminal (CI, nohup). Its kinds are named apart from any domain's
(a domain's kinds say what their jobs typically take, matrix.times)."""
import io
import time
from types import SimpleNamespace

from rich.console import Console

from matrix.display import Estimate, KindStats, RichDisplay, clock
from matrix.runs import Outcome
from matrix.store import Store


def job(key, kind="fit", name=None):
    return SimpleNamespace(key=key, kind=kind, name=name or f"job {key}")


def stats_with(tmp_path, **means):
    stats = KindStats(Store(tmp_path))
    stats.means = {kind: [mean, 5] for kind, mean in means.items()}
    return stats


def test_time_left_starts_from_each_kinds_mean_and_counts_down(tmp_path):
    stats = stats_with(tmp_path, fit=60.0, score=10.0)
    estimate = Estimate(stats, [job("t"), job("o1", "score"), job("o2", "score")], now=0.0)
    assert estimate.left(0.0) == 80.0
    estimate.job_started("t", 0.0)
    assert 60.0 <= estimate.left(20.0) <= 80.0          # counts down, never up, while things go as expected
    estimate.job_finished("t", 60.0)
    assert abs(estimate.raw(60.0) - 20.0) < 1e-9


def test_a_job_running_alone_does_not_make_the_rest_look_one_at_a_time(tmp_path):
    """Two jobs ran at once, then a training runs alone (as it does, on every core) with four jobs after
    it: they will run two at a time again, so the time left is not all of their work end to end."""
    estimate = Estimate(stats_with(tmp_path, fit=10.0, fit_alone=30.0),
                        [job("a1"), job("a2"), job("t", "fit_alone"), *(job(f"b{i}") for i in range(4))], now=0.0)
    for key in ("a1", "a2"):
        estimate.job_started(key, 0.0)
    for key in ("a1", "a2"):
        estimate.job_finished(key, 10.0)
    estimate.job_started("t", 10.0)
    # 20 s of the training left and 40 s of work after it, at 1.5 jobs at once so far (30 job-s in 20 s)
    assert abs(estimate.raw(20.0) - 60.0 / 1.5) < 1e-9
    estimate.job_finished("t", 40.0)
    for key in ("b0", "b1", "b2"):
        estimate.job_finished(key, 50.0)
    assert abs(estimate.raw(50.0) - 10.0) < 1e-9        # one job left: its own time, whatever ran before


def test_the_shown_estimate_does_not_jump_with_a_jumpy_progress(tmp_path):
    estimate = Estimate(stats_with(tmp_path, fit=60.0), [job("t")], now=0.0)
    estimate.job_started("t", 0.0)
    shown, raw = [estimate.left(0.0)], [estimate.raw(0.0)]
    for second, fraction in ((5, 0.5), (10, 0.1), (15, 0.9), (20, 0.2)):   # a progress that leaps about
        estimate.job_progress("t", fraction)
        raw.append(estimate.raw(float(second)))
        shown.append(estimate.left(float(second)))
    def steps(values):
        return max(abs(b - a) for a, b in zip(values, values[1:]))
    assert steps(shown) < 15 < steps(raw), (shown, raw)
    assert all(value >= 0 for value in shown)


def plain_display(tmp_path, interval_s=0.2):
    buffer = io.StringIO()
    console = Console(file=buffer, force_terminal=False, width=100)
    return RichDisplay(Store(tmp_path), console=console, title="toy", interval_s=interval_s), buffer


def test_without_a_terminal_a_status_line_comes_at_a_steady_interval(tmp_path):
    display, buffer = plain_display(tmp_path)
    long_name = "train " + "a_very_long_model_name_" * 8
    display.start([job("t", name=long_name), job("o", "score")])
    display.job_started(job("t", name=long_name))
    display.job_progress("t", completed=3, total=10, description="epoch 3/10")
    time.sleep(0.7)
    display.job_finished(Outcome("t", long_name, "fit", "ok", duration_s=0.7))
    display.stop()
    lines = [line for line in buffer.getvalue().splitlines() if "jobs, elapsed" in line]
    assert len(lines) >= 2, buffer.getvalue()
    first = lines[0]
    assert first.startswith("0/2 jobs, elapsed 0:00:0") and "left" in first and "epoch 3/10" in first
    assert "about 0:00:" in first and long_name not in first and "…" in first


def test_clock_reads_hours_minutes_seconds():
    assert (clock(55), clock(3725.4), clock(-3)) == ("0:00:55", "1:02:05", "0:00:00")


def test_a_kind_new_to_the_store_is_priced_by_the_median_kind_then_by_its_own_finished_jobs(tmp_path):
    # The study's first run on a store that had trained and fine-tuned only: 100 laps were priced at the
    # mean of every kind (a training's 688 s among them), "about 6:51:52 left" for a 40-minute run.
    stats = stats_with(tmp_path, decode=6.0, capture=17.0, fit=688.0)
    laps = [job(f"lap{i}", "drive") for i in range(10)]
    estimate = Estimate(stats, laps, now=0.0)
    assert estimate.raw(0.0) == 10 * 17.0              # the median kind's mean, not (6 + 17 + 688) / 3
    estimate.job_started("lap0", 0.0)
    estimate.job_finished("lap0", 30.0)
    assert abs(estimate.raw(30.0) - 9 * 30.0) < 1e-9   # the run's own laps took 30 s: so will the rest


def test_a_known_kinds_mean_moves_towards_this_runs_jobs(tmp_path):
    stats = stats_with(tmp_path, score=10.0)
    estimate = Estimate(stats, [job(f"o{i}", "score") for i in range(5)], now=0.0)
    estimate.job_started("o0", 0.0)
    estimate.job_finished("o0", 50.0)
    stats.add("score", 50.0, "job o0")    # as the display does when a job finishes: not counted twice
    assert abs(estimate.raw(50.0) - 4 * (3 * 10.0 + 50.0) / 4) < 1e-9


def test_a_kinds_finished_jobs_scale_the_guesses_of_the_rest_by_their_params(tmp_path):
    """The study's display said "about 2:00:41 left" for a 40-minute run: its first lap cell, a Montreal
    tolerance search, became the price of every lap left. The jobs of a kind that finish correct the
    kind's guesses by how far off theirs were: a plain lap that took twice its guess makes a searched
    lap twice its own guess, not a plain lap's time."""
    from matrix.kinds import KINDS, register_kind
    register_kind("drive_toy", lambda ctx: {}, typical_for=lambda params: 6.0 * params["laps"])
    try:
        plain = SimpleNamespace(key="p", kind="drive_toy", name="lap p", params={"laps": 1})
        searched = SimpleNamespace(key="s", kind="drive_toy", name="lap s", params={"laps": 12})
        estimate = Estimate(KindStats(Store(tmp_path)), [plain, searched], now=0.0)
        assert estimate.raw(0.0) == 78.0
        estimate.job_started("p", 0.0)
        estimate.job_finished("p", 12.0)
        assert abs(estimate.raw(12.0) - 144.0) < 1e-9
        # a job of the kind that was not applicable (a cuda lap on a host without a GPU, in 0.1 s) says
        # nothing of how long the others take
        other = SimpleNamespace(key="o", kind="drive_toy", name="lap o", params={"laps": 1})
        estimate = Estimate(KindStats(Store(tmp_path)), [plain, searched, other], now=0.0)
        estimate.job_started("o", 0.0)
        estimate.job_finished("o", 0.1, counted=False)
        assert estimate.raw(0.1) == 78.0
        display, _ = plain_display(tmp_path / "shown")
        display.start([plain, searched])
        display.job_finished(Outcome("p", "lap p", "drive_toy", "ok", duration_s=12.0))
        display.stop()
        assert KindStats(Store(tmp_path / "shown")).estimate("drive_toy", "lap s", searched.params) == 144.0
    finally:
        KINDS._entries.pop("drive_toy")


def test_a_job_that_ran_here_before_is_priced_by_its_own_time(tmp_path):
    stats = KindStats(Store(tmp_path))
    stats.add("tune", 200.0, "optimize pilotnet/qat")
    stats.add("tune", 10.0, "optimize pilotnet/baseline")
    stats.save()
    again = KindStats(Store(tmp_path))
    assert again.estimate("tune", "optimize pilotnet/qat") == 200.0
    assert again.estimate("tune", "optimize pilotnet/new") == again.estimate("tune") == 105.0
    estimate = Estimate(again, [job("q", "tune", "optimize pilotnet/qat"),
                                job("n", "tune", "optimize pilotnet/new")], now=0.0)
    estimate.job_started("n", 0.0)
    estimate.job_finished("n", 1.0)                   # a quick new one does not make qat look quick
    assert estimate.raw(1.0) == 200.0


def test_stats_of_the_first_format_are_read(tmp_path):
    (tmp_path / "stats.json").write_text('{"fit": [60.0, 3], "score": [10.0, 5]}')
    stats = KindStats(Store(tmp_path))
    assert (stats.estimate("fit"), stats.estimate("score", "offline x")) == (60.0, 10.0)
    stats.add("fit", 30.0, "train m")
    stats.save()
    assert KindStats(Store(tmp_path)).estimate("fit", "train m") == 30.0


def test_a_damaged_stats_file_loses_only_its_damaged_entries(tmp_path):
    (tmp_path / "stats.json").write_text('{"format": 2, "kinds": {"fit": [60.0, 3], "score": "x", '
                                         '"drive": [1, 2, 3], "decode": [NaN, 1]}, "names": "not a mapping"}')
    stats = KindStats(Store(tmp_path))
    assert stats.means == {"fit": [60.0, 3]} and stats.names == {}
    assert stats.estimate("score", "offline x") == 60.0
