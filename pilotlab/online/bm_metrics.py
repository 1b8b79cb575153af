"""BehaviorMetrics-compatible closed-loop metrics, beside our metre-based ones (`pilotlab.online.metrics`).

    checkpoints = perfect_lap_checkpoints(expert_trajectory)     # [M, 2], one per expert sample
    bm_run_metrics(trajectory, checkpoints)["bm_position_deviation_mae"]

BehaviorMetrics (JdeRobot, `behavior_metrics/utils/metrics_gazebo.py` and `pilot_gazebo.py`) scores a run
against a "perfect lap": the odometry of an expert's lap, one checkpoint per message. Ours is the
expert brain's lap on the same circuit and direction, one checkpoint per sample (one per brain
iteration). Each function below gives BehaviorMetrics' definition and where we differ; docs/simulator.md
repeats them. The names are those of `pilotlab.columns.BEHAVIORMETRICS` (all start with `bm_`).

A metric that cannot be computed (fewer than two samples, no label ranges, too few decisions for
the trimmed mean) is None, never 0 (BehaviorMetrics writes 0).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from pilotlab.columns import BEHAVIORMETRICS
from pilotlab.online.trajectory import Trajectory

BM_METRICS = tuple(column.name for column in BEHAVIORMETRICS)
REACHED_M = 5.0           # a checkpoint is reached when the car comes this close
WINDOW_SAMPLES = 100      # how far ahead along the run (in samples) a checkpoint's nearest point is sought
TRIM = 10                 # inference times dropped at each end before the mean
SAME_M = 0.01             # nearest-point move below which a checkpoint "converges to the same point"
TIE_M = 0.001             # distances this close count as equally near
CANDIDATE_M = 0.1         # coarse minima this close to the best are refined (the coarse grid's error is smaller)
MAX_CANDIDATES = 20
COARSE = 10               # spline evaluations per sample interval in the first search


def perfect_lap_checkpoints(expert: Trajectory) -> np.ndarray:
    """The perfect lap's checkpoints [M, 2]: the expert lap's positions, one per sample, up to (not
    including) the sample where the lap ended, which is back at the start."""
    points = np.stack([expert.x, expert.y], axis=1)
    return points[:-1] if len(points) > 2 else points


def positions(trajectory: Trajectory) -> np.ndarray:
    return np.stack([trajectory.x, trajectory.y], axis=1)


# position deviation ---------------------------------------------------------------------------------

def _nearest_on_spline(spline: CubicSpline, point: np.ndarray, lo: float, hi: float) -> tuple[float, float]:
    """(t, distance) of the point of the spline nearest `point` with lo <= t <= hi; of points within
    TIE_M of the nearest, the earliest (where the car stood still the spline passes the same place
    many times, and the first pass is the one that counts). A grid of COARSE points per sample
    interval finds the candidate minima, each refined on finer grids."""
    grid = np.linspace(lo, hi, max(2, int(math.ceil((hi - lo) * COARSE)) + 1))
    distances = np.hypot(*(spline(grid) - point).T)
    padded = np.concatenate([[np.inf], distances, [np.inf]])
    minima = np.flatnonzero((distances < padded[:-2]) & (distances <= padded[2:]))
    close = minima[distances[minima] <= distances.min() + CANDIDATE_M]
    # the earliest basins and the nearest ones (a standing car leaves many)
    nearest = close[np.argsort(distances[close], kind="stable")[:MAX_CANDIDATES]]
    candidates = np.union1d(close[:MAX_CANDIDATES], nearest)
    refined = [_refine(spline, point, grid, int(i), lo, hi) for i in candidates]
    best = min(d for _, d in refined)
    return next((t, d) for t, d in refined if d <= best + TIE_M)


def _refine(spline: CubicSpline, point: np.ndarray, grid: np.ndarray, i: int, lo: float, hi: float):
    spacing = grid[1] - grid[0] if len(grid) > 1 else 0.0
    t = float(grid[i])
    for _ in range(3):
        if spacing < 1e-7:
            break
        fine = np.linspace(max(lo, t - spacing), min(hi, t + spacing), 41)
        distances = np.hypot(*(spline(fine) - point).T)
        t, spacing = float(fine[int(np.argmin(distances))]), fine[1] - fine[0]
    return t, float(np.hypot(*(spline(t) - point)))


def _path_length(points: np.ndarray, closed: bool = False) -> float:
    if closed:
        points = np.vstack([points, points[:1]])
    return max(float(np.sum(np.hypot(*np.diff(points, axis=0).T))), 1e-9)


def deviation_distances(run: np.ndarray, checkpoints: np.ndarray) -> np.ndarray:
    """d (metres) of every checkpoint BehaviorMetrics counts. A natural cubic spline runs through
    the run's positions with the sample index as parameter t. The checkpoints are walked in order
    from the one nearest the run's first position; each gets the nearest spline point with t between
    the previous checkpoint's t and WINDOW_SAMPLES further (never beyond the run's last sample). The
    walk stops at the first checkpoint whose nearest point lies in the run's last sample interval
    (the run went no further) or at the fourth checkpoint in a row whose nearest point moved less
    than SAME_M from the previous one's (the car stood still there), as BehaviorMetrics does (it asks
    for t to move less than 0.01, the same thing where the car stands still, but that depends on
    where in the standing stretch of the spline the search lands)."""
    if len(run) < 2 or not len(checkpoints):
        return np.zeros(0)
    last = len(run) - 1
    spline = CubicSpline(np.arange(len(run)), run, bc_type="natural")
    start = int(np.argmin(np.hypot(*(checkpoints - run[0]).T)))
    order = np.roll(checkpoints, -start, axis=0)
    distances, previous, same, here_before = [], 0.0, 0, None
    for k in range(len(order) * (int(_path_length(run) / _path_length(order, closed=True)) + 2)):
        t, d = _nearest_on_spline(spline, order[k % len(order)], previous, min(previous + WINDOW_SAMPLES, last))
        if t > last - 1:
            break
        here = spline(t)
        same = same + 1 if here_before is not None and math.hypot(*(here - here_before)) < SAME_M else 0
        if same > 3:
            break
        distances.append(d)
        previous, here_before = t, here
    return np.asarray(distances)


def deviation_scores(trajectory: Trajectory, checkpoints: np.ndarray) -> np.ndarray:
    return 1000.0 ** deviation_distances(positions(trajectory), checkpoints)


def bm_position_deviation_mae(trajectory: Trajectory, checkpoints: np.ndarray) -> float | None:
    """mean(1000 ** d) over the counted checkpoints: 1.0 for a perfect run, 2.0 at 0.1 m, 31.6 at 0.5 m."""
    scores = deviation_scores(trajectory, checkpoints)
    return float(np.mean(scores)) if len(scores) else None


def bm_position_deviation_total(trajectory: Trajectory, checkpoints: np.ndarray) -> float | None:
    """sum(1000 ** d) over the counted checkpoints (grows with the distance driven)."""
    scores = deviation_scores(trajectory, checkpoints)
    return float(np.sum(scores)) if len(scores) else None


# completion -------------------------------------------------------------------------------------------

def _walk(run: np.ndarray, checkpoints: np.ndarray, first: int, step: int) -> int:
    """Checkpoints reached walking the perfect lap from `first` in direction `step` (+1/-1): the run's
    samples are taken in turn; while the next checkpoint is within REACHED_M of the current sample it
    is counted and the walk moves on to the one after (on the same sample), else the next sample is
    taken. The start checkpoint counts as reached. At most one lap of checkpoints is counted on one
    sample (BehaviorMetrics loops forever on a circuit smaller than 5 m across)."""
    count, index, m = 1, (first + step) % len(checkpoints), len(checkpoints)
    for sample in run[1:]:
        on_this_sample = 0
        while on_this_sample < m and math.hypot(*(checkpoints[index] - sample)) < REACHED_M:
            count, index, on_this_sample = count + 1, (index + step) % m, on_this_sample + 1
    return count


def bm_percentage_completed(trajectory: Trajectory, checkpoints: np.ndarray) -> float | None:
    """100 × checkpoints reached / checkpoints in the perfect lap, the better of the two walking
    directions. It reads more than 100 after a lap, and about 5 m ahead of where the car got to."""
    run = positions(trajectory)
    if not len(checkpoints):
        return None
    first = int(np.argmin(np.hypot(*(checkpoints - run[0]).T)))
    reached = max(_walk(run, checkpoints, first, +1), _walk(run, checkpoints, first, -1))
    return 100.0 * reached / len(checkpoints)


def bm_lap_completed(trajectory: Trajectory, checkpoints: np.ndarray) -> bool | None:
    """BehaviorMetrics' rule: percentage completed above 100."""
    percentage = bm_percentage_completed(trajectory, checkpoints)
    return None if percentage is None else bool(percentage > 100.0)


def bm_completed_distance_m(trajectory: Trajectory, checkpoints: np.ndarray | None = None) -> float:
    """The car's path length: the sum of the distances between consecutive positions."""
    return float(np.sum(np.hypot(np.diff(trajectory.x), np.diff(trajectory.y))))


def bm_average_speed(trajectory: Trajectory, checkpoints: np.ndarray | None = None) -> float | None:
    """Path length over the whole seconds of the simulated clock between the first and the last
    sample (BehaviorMetrics reads `clock.secs`, dropping the nanoseconds); None within one second."""
    seconds = math.floor(trajectory.t[-1]) - math.floor(trajectory.t[0])
    return bm_completed_distance_m(trajectory) / seconds if seconds > 0 else None


# the brain ---------------------------------------------------------------------------------------------

def bm_brain_frequency_sim_hz(trajectory: Trajectory, checkpoints: np.ndarray | None = None) -> float | None:
    """1 / the mean simulated duration of one iteration (from its camera image to the next one's,
    the last ending with the run)."""
    durations = np.diff(trajectory.t[np.append(trajectory.decisions, len(trajectory) - 1)])
    mean = float(np.mean(durations)) if len(durations) else 0.0
    return 1.0 / mean if mean > 0 else None


def bm_brain_frequency_real_hz(trajectory: Trajectory, checkpoints: np.ndarray | None = None) -> float | None:
    """1 / the mean time of one brain iteration (`brain.execute()`, without the cycle's sleep): in the
    replay timing mode the replayed time, else the wall clock."""
    times = trajectory.brain_s[trajectory.decisions]
    return 1.0 / float(np.mean(times)) if len(times) and np.mean(times) > 0 else None


def bm_mean_inference_ms(trajectory: Trajectory, checkpoints: np.ndarray | None = None) -> float | None:
    """Mean inference time with the first and last TRIM dropped; None with 2 × TRIM decisions or fewer
    (BehaviorMetrics divides by zero there)."""
    times = trajectory.inference_s[trajectory.decisions]
    return 1000.0 * float(np.mean(times[TRIM:-TRIM])) if len(times) > 2 * TRIM else None


def bm_suddenness(trajectory: Trajectory, checkpoints: np.ndarray | None = None) -> float | None:
    """Mean Euclidean distance between consecutive normalised (v, w) outputs, normalised with the
    network's label ranges ((x - lo) / (hi - lo)); None for a brain without them (the references)."""
    ranges = trajectory.meta.get("label_ranges")
    index = trajectory.decisions
    if not ranges or len(index) < 2:
        return None
    v = (trajectory.v[index] - ranges["v"][0]) / (ranges["v"][1] - ranges["v"][0])
    w = (trajectory.w[index] - ranges["w"][0]) / (ranges["w"][1] - ranges["w"][0])
    return float(np.mean(np.hypot(np.diff(v), np.diff(w))))


FUNCTIONS = {name: globals()[name] for name in BM_METRICS}


def bm_run_metrics(trajectory: Trajectory, checkpoints: np.ndarray) -> dict[str, Any]:
    """Every BehaviorMetrics-compatible metric of one run against the perfect lap's checkpoints."""
    distances = deviation_distances(positions(trajectory), checkpoints)
    scores = 1000.0 ** distances
    shared = {"bm_position_deviation_mae": float(np.mean(scores)) if len(scores) else None,
              "bm_position_deviation_total": float(np.sum(scores)) if len(scores) else None}
    percentage = bm_percentage_completed(trajectory, checkpoints)
    shared |= {"bm_percentage_completed": percentage,
               "bm_lap_completed": None if percentage is None else bool(percentage > 100.0)}
    return {name: shared[name] if name in shared else function(trajectory, checkpoints)
            for name, function in FUNCTIONS.items()}
