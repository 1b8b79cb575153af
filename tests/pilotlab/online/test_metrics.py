"""The metric functions on synthetic trajectories whose answers are worked out by hand."""
import numpy as np
import pytest

from pilotlab.columns import ONLINE
from pilotlab.errors import PilotlabError
from pilotlab.online.metrics import METRICS, aggregate, lap_seconds, run_metrics
from pilotlab.online.trajectory import Trajectory, load_npz, save_csv, save_npz


def synthetic(t, progress, lateral, length, *, speed=None, off_road=None, v=None, w=None, brain_s=0.01,
              inference_s=0.004, wall_factor=0.25):
    """A trajectory with a decision at every sample but the last (as `drive` records them)."""
    t = np.asarray(t, float)
    n = len(t)
    decided = lambda values, default: np.append(np.broadcast_to(default if values is None else values, n - 1), np.nan)
    return Trajectory(t=t, wall=t * wall_factor, x=np.asarray(progress, float),
                      y=np.asarray(lateral, float) + np.zeros(n),
                      yaw=np.zeros(n), speed=np.zeros(n) if speed is None else speed, progress=progress,
                      lateral=np.broadcast_to(lateral, n), off_road=np.zeros(n, bool) if off_road is None else off_road,
                      v=decided(v, 5.0), w=decided(w, 0.0), brain_s=decided(None, brain_s),
                      inference_s=decided(None, inference_s), charged_s=decided(None, 0.0), circuit_length=length)


def test_metric_names_are_the_online_columns():
    assert METRICS == tuple(c.name for c in ONLINE)


def test_a_straight_path_one_metre_left_of_the_line():
    # 10 s at 5 m/s, sampled every 0.5 s (21 samples, 20 decisions), 1 m off the line all the way, on a 100 m circuit.
    t = np.arange(21) * 0.5
    metrics = run_metrics(synthetic(t, 5.0 * t, 1.0, 100.0))
    assert metrics["completed_distance_m"] == pytest.approx(50.0)
    assert metrics["percentage_completed"] == pytest.approx(50.0)
    assert metrics["lap_completed"] is False and metrics["lap_seconds"] is None
    assert metrics["average_speed"] == pytest.approx(5.0)
    assert metrics["position_deviation_mae_m"] == pytest.approx(1.0)
    assert metrics["position_deviation_total_m"] == pytest.approx(21.0)     # one metre at each of 21 samples
    assert metrics["brain_frequency_sim_hz"] == pytest.approx(2.0)          # 20 decisions in 10 s
    assert metrics["brain_frequency_real_hz"] == pytest.approx(100.0)       # 10 ms per brain iteration
    assert metrics["mean_inference_ms"] == pytest.approx(4.0)
    assert metrics["real_time_factor"] == pytest.approx(4.0)                # wall clock ran at a quarter
    assert metrics["suddenness"] == pytest.approx(0.0)                      # the same command every time
    assert metrics["off_road_events"] == 0


def test_a_path_that_stops_half_way():
    # 100 m at 10 m/s on a 200 m circuit, then standing still until the 30 s timeout.
    t = np.arange(0, 30.001, 0.05)
    progress = np.minimum(10.0 * t, 100.0)
    metrics = run_metrics(synthetic(t, progress, 0.0, 200.0))
    assert metrics["completed_distance_m"] == pytest.approx(100.0)
    assert metrics["percentage_completed"] == pytest.approx(50.0)
    assert metrics["lap_completed"] is False and metrics["lap_seconds"] is None
    assert metrics["average_speed"] == pytest.approx(100.0 / 30.0)
    assert metrics["position_deviation_mae_m"] == 0.0
    assert metrics["brain_frequency_sim_hz"] == pytest.approx(20.0)


def test_the_whole_of_a_shorter_drive_asked_for_is_a_completed_lap():
    """Outside test: with `laps: 0.2` every brain that drove the 20 % asked for was reported "✗ lost"."""
    t = np.arange(21) * 0.5
    asked = synthetic(t, 5.0 * t, 0.0, 250.0)
    asked.meta["termination"] = "lap_completed"   # the env stops at laps × length (here 0.2 × 250 m)
    assert run_metrics(asked)["lap_completed"] is True and run_metrics(asked)["lap_seconds"] is None
    asked.meta["termination"] = "off_road"        # the same distance, then off the road: lost
    assert run_metrics(asked)["lap_completed"] is False


def test_a_lap_done_twice():
    # 10 m/s round a 100 m circuit for 20 s, sampled every 0.3 s: the lap ends between two samples, at 10 s.
    t = np.arange(0, 20.0001, 0.3)
    t = np.append(t, 20.0)
    metrics = run_metrics(synthetic(t, 10.0 * t, -0.5, 100.0))
    assert metrics["lap_completed"] is True
    assert metrics["lap_seconds"] == pytest.approx(10.0)
    assert metrics["completed_distance_m"] == pytest.approx(200.0)
    assert metrics["percentage_completed"] == pytest.approx(200.0)
    assert metrics["average_speed"] == pytest.approx(10.0)
    assert metrics["position_deviation_mae_m"] == pytest.approx(0.5)        # the distance, whichever side


def test_lap_time_counts_from_the_first_sample():
    t = np.array([5.0, 6.0, 7.0])
    assert lap_seconds(synthetic(t, [0.0, 60.0, 120.0], 0.0, 100.0)) == pytest.approx(1 + 40 / 60)


def test_suddenness_is_the_mean_change_between_consecutive_commands():
    # Commands (5, 0) -> (5, 0.3) -> (5.4, 0.3): changes of 0.3 and 0.4; the last sample has none.
    trajectory = synthetic(np.arange(4.0), np.arange(4.0), 0.0, 100.0, v=[5.0, 5.0, 5.4], w=[0.0, 0.3, 0.3])
    assert run_metrics(trajectory)["suddenness"] == pytest.approx(0.35)


def test_off_road_events_count_each_time_the_car_leaves_the_road():
    t = np.arange(6.0)
    runs = {(False, True, True, False, True, False): 2, (True, False, False, False, False, False): 1,
            (False,) * 6: 0}
    for pattern, events in runs.items():
        assert run_metrics(synthetic(t, t, 0.0, 100.0, off_road=np.array(pattern)))["off_road_events"] == events


def test_metrics_that_cannot_be_computed_are_none_not_zero():
    single = run_metrics(synthetic(np.array([0.0, 0.05]), [0.0, 0.0], 0.0, 100.0))
    assert single["suddenness"] is None and single["lap_seconds"] is None


def test_mean_and_spread_over_repetitions():
    t = np.arange(21) * 0.5
    near = run_metrics(synthetic(t, 5.0 * t, 0.2, 100.0))
    far = run_metrics(synthetic(t, 5.0 * t, 0.6, 100.0))
    lap = run_metrics(synthetic(np.arange(0, 11.0), 10.0 * np.arange(0, 11.0), 0.4, 100.0))
    means, spread = aggregate([near, far, lap])
    assert means["position_deviation_mae_m"] == pytest.approx(0.4)
    assert spread["position_deviation_mae_m"]["std"] == pytest.approx(0.2)   # sample std of 0.2, 0.6, 0.4
    deviation = spread["position_deviation_mae_m"]
    assert (deviation["min"], deviation["max"]) == pytest.approx((0.2, 0.6))
    assert means["lap_completed"] is False and spread["lap_completed"] == {"completed": 1, "runs": 3}
    assert means["lap_seconds"] == pytest.approx(10.0) and spread["lap_seconds"]["runs"] == 1
    alone, alone_spread = aggregate([lap])
    assert alone["lap_completed"] is True and alone_spread["average_speed"]["std"] == 0.0


def test_trajectories_round_trip_through_npz_and_csv(tmp_path):
    t = np.arange(5) * 0.5
    first = synthetic(t, 5.0 * t, 1.0, 100.0, off_road=np.array([0, 0, 1, 1, 0], bool))
    first.meta.update(termination="timeout", start_m=12.5)
    second = synthetic(t[:3], t[:3], -1.0, 100.0)
    loaded = load_npz(save_npz([first, second], tmp_path / "runs.npz"))
    assert len(loaded) == 2 and loaded[0].meta == first.meta and loaded[1].circuit_length == 100.0
    for column, values in first.columns().items():
        np.testing.assert_array_equal(getattr(loaded[0], column), values)
    lines = save_csv([first, second], tmp_path / "runs.csv").read_text().splitlines()
    assert lines[0].startswith("run,t,wall,x,y") and len(lines) == 1 + 5 + 3
    assert lines[5].split(",")[0] == "0" and lines[5].split(",")[10] == ""   # the last sample has no command
    assert lines[3].split(",")[9] == "1"                                      # off_road as 0/1


def test_a_trajectory_needs_columns_of_one_length():
    with pytest.raises(PilotlabError, match="one non-zero length"):
        Trajectory(*(np.zeros(3),) * 13, np.zeros(2), circuit_length=10.0)
