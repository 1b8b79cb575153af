"""The run's display: time left labelled and smoothed, long names cut, and a status line at a steady
interval when the output is not a terminal (CI, nohup)."""
import io
import time
from types import SimpleNamespace

from rich.console import Console

from matrix.display import Estimate, KindStats, RichDisplay, clock
from matrix.runs import Outcome
from matrix.store import Store


def job(key, kind="train", name=None):
    return SimpleNamespace(key=key, kind=kind, name=name or f"job {key}")


def stats_with(tmp_path, **means):
    stats = KindStats(Store(tmp_path))
    stats.means = {kind: [mean, 5] for kind, mean in means.items()}
    return stats


def test_time_left_starts_from_each_kinds_mean_and_counts_down(tmp_path):
    stats = stats_with(tmp_path, train=60.0, offline=10.0)
    estimate = Estimate(stats, [job("t"), job("o1", "offline"), job("o2", "offline")], now=0.0)
    assert estimate.left(0.0) == 80.0
    estimate.job_started("t", 0.0)
    assert 60.0 <= estimate.left(20.0) <= 80.0          # counts down, never up, while things go as expected
    estimate.job_finished("t", 60.0)
    assert abs(estimate.raw(60.0) - 20.0) < 1e-9


def test_the_shown_estimate_does_not_jump_with_a_jumpy_progress(tmp_path):
    estimate = Estimate(stats_with(tmp_path, train=60.0), [job("t")], now=0.0)
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
    display.start([job("t", name=long_name), job("o", "offline")])
    display.job_started(job("t", name=long_name))
    display.job_progress("t", completed=3, total=10, description="epoch 3/10")
    time.sleep(0.7)
    display.job_finished(Outcome("t", long_name, "train", "ok", duration_s=0.7))
    display.stop()
    lines = [line for line in buffer.getvalue().splitlines() if "jobs, elapsed" in line]
    assert len(lines) >= 2, buffer.getvalue()
    first = lines[0]
    assert first.startswith("0/2 jobs, elapsed 0:00:0") and "left" in first and "epoch 3/10" in first
    assert "about 0:00:" in first and long_name not in first and "…" in first


def test_clock_reads_hours_minutes_seconds():
    assert (clock(55), clock(3725.4), clock(-3)) == ("0:00:55", "1:02:05", "0:00:00")
