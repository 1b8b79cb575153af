"""BehaviorMetrics-compatible metrics against an independent implementation written here from the
definitions (BehaviorMetrics' metrics_gazebo.py / pilot_gazebo.py, as docs/simulator.md states them),
on synthetic trajectories and on laps driven in the simulator."""
import math

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.optimize import minimize_scalar

from pilotlab.columns import BEHAVIORMETRICS
from pilotlab.online.bm_metrics import BM_METRICS, bm_run_metrics, perfect_lap_checkpoints
from pilotlab.online.brains import make_reference_brain
from pilotlab.online.drive import DriveSettings, drive
from pilotlab.online.perfect_lap import perfect_lap
from pilotlab.online.trajectory import Trajectory
from pilotlab.sim.env import DrivingEnv
from tests.pilotlab.tracks import stadium, write_csv


# the independent implementation ------------------------------------------------------------------------

def reference_deviation(xs, ys, checkpoints):
    """For each checkpoint from the one nearest the run's start: the nearest point of a natural cubic
    spline x(t), y(t) through the run (t = sample index), searched forward from the previous
    checkpoint's t, at most 100 samples ahead; stop when it falls in the last interval or the nearest
    point stays put (within 1 cm) for a 4th checkpoint in a row."""
    n = len(xs)
    sx, sy = CubicSpline(range(n), xs, bc_type="natural"), CubicSpline(range(n), ys, bc_type="natural")
    start = min(range(len(checkpoints)), key=lambda i: math.dist(checkpoints[i], (xs[0], ys[0])))
    scores, previous, same, k = [], 0.0, 0, 0
    while k < 20 * len(checkpoints):
        cx, cy = checkpoints[(start + k) % len(checkpoints)]
        distance = lambda t: np.hypot(cx - sx(t), cy - sy(t))
        hi = min(previous + 100, n - 1)
        grid = np.linspace(previous, hi, int((hi - previous) * 50) + 2)
        distances = distance(grid)
        local = [i for i in range(len(grid)) if (i == 0 or distances[i] < distances[i - 1])
                 and (i == len(grid) - 1 or distances[i] <= distances[i + 1]) and distances[i] <= distances.min() + 0.1]
        found = []
        for i in local:
            best = minimize_scalar(distance, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]),
                                   method="bounded", options={"xatol": 1e-7})
            found.append((best.x, best.fun) if best.fun < distances[i] else (grid[i], distances[i]))
        nearest = min(d for _, d in found)
        t = next(t for t, d in found if d <= nearest + 0.001)    # the earliest of the nearest points
        if t > n - 2:
            break
        here = (float(sx(t)), float(sy(t)))
        same = same + 1 if k and math.dist(here, before) < 0.01 else 0
        if same > 3:
            break
        scores.append(1000 ** distance(t))
        previous, before, k = t, here, k + 1
    return scores


def reference_walk(xs, ys, checkpoints, step):
    m = len(checkpoints)
    first = min(range(m), key=lambda i: math.dist(checkpoints[i], (xs[0], ys[0])))
    reached, index, i = 1, (first + step) % m, 1
    while i < len(xs):
        if math.dist(checkpoints[index], (xs[i], ys[i])) < 5:
            reached += 1
            index = (index + step) % m
        else:
            i += 1
    return reached


def reference_metrics(trajectory: Trajectory, checkpoints):
    xs, ys, t = list(trajectory.x), list(trajectory.y), list(trajectory.t)
    scores = reference_deviation(xs, ys, [tuple(c) for c in checkpoints])
    reached = max(reference_walk(xs, ys, checkpoints, +1), reference_walk(xs, ys, checkpoints, -1))
    percentage = 100 * reached / len(checkpoints)
    path = sum(math.dist((xs[i], ys[i]), (xs[i + 1], ys[i + 1])) for i in range(len(xs) - 1))
    decided = [i for i in range(len(t)) if not math.isnan(trajectory.v[i])]
    iteration_times = [t[j] - t[i] for i, j in zip(decided, decided[1:] + [len(t) - 1])]
    inference = [trajectory.inference_s[i] for i in decided][10:-10]
    result = {"bm_position_deviation_mae": sum(scores) / len(scores), "bm_position_deviation_total": sum(scores),
              "bm_percentage_completed": percentage, "bm_lap_completed": percentage > 100,
              "bm_completed_distance_m": path, "bm_average_speed": path / (int(t[-1]) - int(t[0])),
              "bm_brain_frequency_sim_hz": 1 / (sum(iteration_times) / len(iteration_times)),
              "bm_brain_frequency_real_hz": len(decided) / sum(trajectory.brain_s[i] for i in decided),
              "bm_mean_inference_ms": 1000 * sum(inference) / len(inference) if inference else None}
    ranges = trajectory.meta.get("label_ranges")
    if ranges:
        norm = [((trajectory.v[i] - ranges["v"][0]) / (ranges["v"][1] - ranges["v"][0]),
                 (trajectory.w[i] - ranges["w"][0]) / (ranges["w"][1] - ranges["w"][0])) for i in decided]
        result["bm_suddenness"] = sum(math.dist(a, b) for a, b in zip(norm, norm[1:])) / (len(norm) - 1)
    return result


def assert_match(trajectory, checkpoints):
    ours, theirs = bm_run_metrics(trajectory, checkpoints), reference_metrics(trajectory, checkpoints)
    for name, expected in theirs.items():
        if isinstance(expected, bool) or expected is None:
            assert ours[name] == expected, name
        else:
            assert ours[name] == pytest.approx(expected, rel=0.01), name
    return ours


# synthetic trajectories -------------------------------------------------------------------------------------

def circle(radius, count, turns=1.0, start=0.0):
    angles = start - np.linspace(0, 2 * np.pi * turns, count, endpoint=False)   # clockwise
    return np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)


def synthetic(points, dt=0.05, ranges=None, rng=None):
    n = len(points)
    decided = lambda values: np.append(values[: n - 1], np.nan)
    rng = rng or np.random.default_rng(0)
    return Trajectory(t=np.arange(n) * dt, wall=np.arange(n) * dt, x=points[:, 0], y=points[:, 1], yaw=np.zeros(n),
                      speed=np.zeros(n), progress=np.zeros(n), lateral=np.zeros(n), off_road=np.zeros(n, bool),
                      v=decided(5 + rng.normal(0, 0.5, n)), w=decided(rng.normal(0, 0.3, n)),
                      brain_s=decided(rng.uniform(0.01, 0.03, n)), inference_s=decided(rng.uniform(0.004, 0.02, n)),
                      charged_s=decided(np.zeros(n)), circuit_length=2 * np.pi * 20,
                      meta={"label_ranges": ranges})


CHECKPOINTS = circle(20.0, 250)


def test_the_bm_metric_names_are_the_columns():
    assert BM_METRICS == tuple(column.name for column in BEHAVIORMETRICS)


def test_a_lap_0_2_m_outside_the_perfect_one_scores_1000_to_the_0_2():
    run = circle(20.2, 300, turns=1.0)
    metrics = assert_match(synthetic(np.vstack([run, run[:1]])), CHECKPOINTS)
    assert metrics["bm_position_deviation_mae"] == pytest.approx(1000 ** 0.2, rel=0.01)
    assert metrics["bm_lap_completed"] and 100 < metrics["bm_percentage_completed"] < 106


def test_a_wobbly_lap():
    angles = np.linspace(0, 2 * np.pi, 400)
    radius = 20 + 0.6 * np.sin(9 * angles)
    run = np.stack([radius * np.cos(-angles), radius * np.sin(-angles)], axis=1)
    metrics = assert_match(synthetic(run, ranges={"v": [0, 10], "w": [-2, 2]}), CHECKPOINTS)
    assert metrics["bm_position_deviation_mae"] > 10


def test_a_run_that_stops_half_way_and_stands_still():
    run = np.vstack([circle(20.0, 150, turns=0.5), np.repeat(circle(20.0, 1, start=-np.pi), 60, axis=0)])
    metrics = assert_match(synthetic(run), CHECKPOINTS)
    assert not metrics["bm_lap_completed"] and 50 < metrics["bm_percentage_completed"] < 56


def test_perfect_lap_checkpoints_leave_out_the_sample_back_at_the_start():
    run = synthetic(np.vstack([CHECKPOINTS, CHECKPOINTS[:1]]))
    assert len(perfect_lap_checkpoints(run)) == len(CHECKPOINTS)


# laps driven in pilotlab -----------------------------------------------------------------------------------

class LeavesHalfWay:
    """The expert until half the lap, then a hard turn off the road."""
    name, needs_camera, last_inference_s = "leaves", False, 0.0

    def __init__(self):
        self.expert = make_reference_brain("expert")

    def reset(self, circuit):
        self.expert.reset(circuit)
        self.half = circuit.length / 2

    def act(self, image, info):
        return (6.0, 1.5) if info["progress"] > self.half else self.expert.act(image, info)


@pytest.fixture(scope="module")
def track(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bm")
    path = write_csv(folder / "stadium.csv", stadium(30.0, 12.0))
    checkpoints = perfect_lap(str(path), cache=folder / "cache")
    np.testing.assert_array_equal(perfect_lap(str(path), cache=folder / "cache"), checkpoints)   # the cached one
    return str(path), checkpoints


def lap(track, brain, **settings):
    with DrivingEnv(track, camera=None, laps=1, timeout_s=60.0) as env:
        return drive(env, brain, DriveSettings(**settings))


def test_a_good_lap_driven_by_the_expert(track):
    path, checkpoints = track
    trajectory = lap(path, make_reference_brain("expert"), timing="lockstep")
    metrics = assert_match(trajectory, checkpoints)
    assert trajectory.termination == "lap_completed" and metrics["bm_lap_completed"]
    assert metrics["bm_position_deviation_mae"] < 1.2


def test_a_wobbly_lap_driven_late(track):
    path, checkpoints = track
    trajectory = lap(path, make_reference_brain("expert"), fixed_inference_ms=90.0)
    metrics = assert_match(trajectory, checkpoints)
    assert metrics["bm_position_deviation_mae"] > 1.2


def test_a_lap_that_leaves_the_road_half_way(track):
    path, checkpoints = track
    trajectory = lap(path, LeavesHalfWay(), timing="lockstep")
    metrics = assert_match(trajectory, checkpoints)
    assert trajectory.termination == "off_road" and not metrics["bm_lap_completed"]
    assert 45 < metrics["bm_percentage_completed"] < 70


def test_the_cached_perfect_lap_follows_every_module_that_drives_it(monkeypatch):
    """Outside test: the cache key hashed a hand-kept list of modules that left out the expert's brain
    (pilotlab.online.brains) and its smoothing (pilotlab.circuits.geometry): an edit there scored new
    laps against the old expert's lap. The key now hashes the computed import closure."""
    from matrix import fingerprint
    from pilotlab.online import perfect_lap as module
    points = stadium(30.0, 12.0)
    before = module._key(points, 7.0)
    closure = fingerprint.module_closure(module.__name__, "pilotlab")
    assert {"pilotlab.online.brains", "pilotlab.circuits.geometry", "pilotlab.sim.expert"} <= set(closure)
    monkeypatch.setitem(fingerprint._SOURCE_HASHES, "pilotlab.online.brains#own", "edited")
    assert module._key(points, 7.0) != before
