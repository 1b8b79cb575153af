"""BehaviorMetrics' closed-loop metrics, as pure functions of a `Trajectory`.

Names and units are those of `pilotlab.columns.ONLINE`. Each function says what BehaviorMetrics
(JdeRobot, `behavior_metrics/utils/metrics.py` and `pilot.py`, Gazebo follow-line F1) computes and
where we differ, so our numbers can be read next to the 2022 study's:

- completed_distance_m: metres driven along the red line (the last sample's progress). BehaviorMetrics
  sums the distances between consecutive odometry positions (the car's own path length), which a car
  that zig-zags inflates; progress along the line does not.
- percentage_completed: completed distance over the circuit's length, × 100 (more than 100 after a
  lap, as BehaviorMetrics' `+ laps * 100`).
- lap_completed: the car got round at least once (or drove the whole of a shorter distance asked for,
  `laps` < 1); lap_seconds: simulated seconds from the start to
  the moment progress reached one circuit length (interpolated between the two samples around it).
  BehaviorMetrics detects the car back within 1 m of its start point after 10 s.
- average_speed: completed distance over the simulated duration of the run (BehaviorMetrics: its
  completed distance over the simulated clock's span).
- position_deviation_mae_m / _total_m: mean / sum over the samples (one per brain iteration, plus
  the last) of the car's distance from the red line, in metres. BehaviorMetrics' numbers are NOT
  metres: for every point of a "perfect lap" it finds the nearest point of a spline through the
  car's positions and adds `1000 ** distance`, so its MAE is an exponential score (0.1 m -> 2.0,
  0.5 m -> 31.6) that cannot be compared with ours; `pilotlab.online.bm_metrics` computes it (and
  BehaviorMetrics' other definitions) beside ours, as the `bm_*` columns.
- brain_frequency_sim_hz: brain iterations per simulated second: 1 / the mean simulated time between
  consecutive decisions, as BehaviorMetrics (1 / the mean simulated duration of an iteration).
- brain_frequency_real_hz: 1 / the mean wall-clock time of one brain iteration (camera image in,
  command out), as BehaviorMetrics times `brain.execute()`; that is the rate the brain can sustain,
  independent of how fast the simulator renders. (BehaviorMetrics' pilot loop also sleeps up to its
  50 ms cycle inside the measured time in some versions; the study's 58-99 Hz figures show it did not.)
- mean_inference_ms: mean time of one decision (the network's predict call; a reference brain's
  whole computation), artificial latency included, as BehaviorMetrics' `inference_times` (which
  drop the first and last 10; we warm the network up before the run instead). In replay timing a
  reference brain is charged none, so its lap reports none (pilotlab.jobs.online).
- real_time_factor: simulated seconds per wall-clock second over the run (BehaviorMetrics averages
  Gazebo's own real-time factor).
- suddenness: mean Euclidean change between consecutive (v, w) commands, in physical units (m/s and
  rad/s). BehaviorMetrics' `suddenness_distance` takes the network's normalised outputs, so its value
  depends on each network's label ranges; physical commands let every brain (the explicit one and
  the expert included) be measured the same way.
- off_road_events: times the car's centre went from the road to off it (a run that starts off the
  road counts one). BehaviorMetrics has no such metric.

A metric that cannot be computed (no lap, fewer than two decisions) is None, never 0.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from pilotlab.columns import ONLINE
from pilotlab.online.trajectory import Trajectory

METRICS = tuple(column.name for column in ONLINE)


def duration_s(trajectory: Trajectory) -> float:
    return float(trajectory.t[-1] - trajectory.t[0])


def completed_distance_m(trajectory: Trajectory) -> float:
    return max(0.0, float(trajectory.progress[-1]))


def percentage_completed(trajectory: Trajectory) -> float:
    return 100.0 * completed_distance_m(trajectory) / trajectory.circuit_length


def lap_completed(trajectory: Trajectory) -> bool:
    """Round at least once, or the whole of a shorter drive asked for (`laps` < 1: the run ends with
    termination "lap_completed" there; counting it lost made every short lap's verdict "lost")."""
    return bool(np.max(trajectory.progress) >= trajectory.circuit_length
                or trajectory.termination == "lap_completed")


def lap_seconds(trajectory: Trajectory) -> float | None:
    """Simulated seconds until progress first reached one lap, interpolated between samples."""
    progress, length = trajectory.progress, trajectory.circuit_length
    reached = np.flatnonzero(progress >= length)
    if not len(reached):
        return None
    i = int(reached[0])
    if i == 0:
        return 0.0
    fraction = (length - progress[i - 1]) / (progress[i] - progress[i - 1])
    return float(trajectory.t[i - 1] + fraction * (trajectory.t[i] - trajectory.t[i - 1]) - trajectory.t[0])


def average_speed(trajectory: Trajectory) -> float | None:
    seconds = duration_s(trajectory)
    return completed_distance_m(trajectory) / seconds if seconds > 0 else None


def position_deviation_mae_m(trajectory: Trajectory) -> float:
    return float(np.mean(np.abs(trajectory.lateral)))


def position_deviation_total_m(trajectory: Trajectory) -> float:
    return float(np.sum(np.abs(trajectory.lateral)))


def brain_frequency_sim_hz(trajectory: Trajectory) -> float | None:
    """1 / the mean simulated time between consecutive decisions (the run's stop may cut the last
    iteration short, so it is left out)."""
    times = trajectory.t[trajectory.decisions]
    return (len(times) - 1) / float(times[-1] - times[0]) if len(times) > 1 and times[-1] > times[0] else None


def brain_frequency_real_hz(trajectory: Trajectory) -> float | None:
    times = trajectory.brain_s[trajectory.decisions]
    return 1.0 / float(np.mean(times)) if len(times) and np.mean(times) > 0 else None


def mean_inference_ms(trajectory: Trajectory) -> float | None:
    times = trajectory.inference_s[trajectory.decisions]
    return 1000.0 * float(np.mean(times)) if len(times) else None


def real_time_factor(trajectory: Trajectory) -> float | None:
    wall = float(trajectory.wall[-1] - trajectory.wall[0])
    return duration_s(trajectory) / wall if wall > 0 else None


def suddenness(trajectory: Trajectory) -> float | None:
    index = trajectory.decisions
    if len(index) < 2:
        return None
    commands = np.stack([trajectory.v[index], trajectory.w[index]], axis=1)
    return float(np.mean(np.linalg.norm(np.diff(commands, axis=0), axis=1)))


def off_road_events(trajectory: Trajectory) -> int:
    off = trajectory.off_road.astype(np.int8)
    return int(off[0] + np.count_nonzero(np.diff(off) == 1))


FUNCTIONS = {name: globals()[name] for name in METRICS}


def run_metrics(trajectory: Trajectory) -> dict[str, Any]:
    """Every ONLINE metric of one run (None where it cannot be computed)."""
    return {name: function(trajectory) for name, function in FUNCTIONS.items()}


def aggregate(runs: Sequence[dict[str, Any]], names: Sequence[str] = METRICS
              ) -> tuple[dict[str, Any], dict[str, dict[str, float]]]:
    """(mean, spread) over repetitions. The mean of each metric is over the runs that have it
    (lap_seconds: over the completed laps); `lap_completed` is True only when every run completed
    its lap. The spread gives std (sample standard deviation; 0 for one run), min and max, and for
    lap_completed the number of runs that completed. `names`: the metrics to aggregate (BehaviorMetrics'
    `bm_` ones too; `bm_lap_completed` as lap_completed)."""
    means: dict[str, Any] = {}
    spread: dict[str, dict[str, float]] = {}
    for name in names:
        values = [run[name] for run in runs if run.get(name) is not None]
        if not values:
            continue
        if name.endswith("lap_completed"):
            means[name] = all(values) and len(values) == len(runs)
            spread[name] = {"completed": sum(bool(v) for v in values), "runs": len(runs)}
            continue
        array = np.asarray(values, dtype=np.float64)
        means[name] = values[0] if len(values) == 1 else float(array.mean())
        spread[name] = {"std": float(array.std(ddof=1)) if len(array) > 1 else 0.0,
                        "min": float(array.min()), "max": float(array.max()), "runs": len(array)}
    return means, spread
