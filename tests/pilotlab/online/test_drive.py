"""The closed loop in the real simulator, on short stretches of road: what each timing mode charges,
reproducibility, late reactions, stop rules."""
import time

import numpy as np
import pydantic
import pytest

from pilotlab.errors import PilotlabError
from pilotlab.online.brains import make_reference_brain
from pilotlab.online.drive import DriveSettings, drive
from pilotlab.online.metrics import run_metrics
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv

STATE = ("t", "x", "y", "yaw", "speed", "progress", "lateral", "v", "w", "charged_s")


class Constant:
    """A brain that always sends the same command."""
    name, needs_camera, last_inference_s = "constant", False, 0.0

    def __init__(self, v: float, w: float):
        self.command = (v, w)

    def reset(self, circuit) -> None:
        pass

    def warm_up(self) -> None:
        pass

    def act(self, image, info):
        return self.command


def expert_run(circuit="simple_circuit", timeout_s=4.0, latency_ms=None, seed=0, **settings):
    with DrivingEnv(circuit, camera=None, timeout_s=timeout_s) as env:
        return drive(env, make_reference_brain("expert"), DriveSettings(**settings), latency_ms=latency_ms, seed=seed)


@pytest.mark.parametrize("timing", ["replay", "measured"])
def test_a_fixed_inference_time_is_reproducible(timing):
    first, second = (expert_run(timing=timing, fixed_inference_ms=20.0) for _ in range(2))
    for column in STATE:
        np.testing.assert_array_equal(getattr(first, column), getattr(second, column))
    assert first.termination == "timeout" and first.t[-1] == pytest.approx(4.0)


@pytest.mark.parametrize("inference_ms, iteration_s, charged_s", [(0.0, 0.05, 0.0), (30.0, 0.05, 4 / 120),
                                                                    (120.0, 15 / 120, 15 / 120)])
def test_replay_charges_max_of_period_and_inference_time(inference_ms, iteration_s, charged_s):
    trajectory = expert_run(timeout_s=2.0, fixed_inference_ms=inference_ms)
    decisions = trajectory.decisions
    np.testing.assert_allclose(np.diff(trajectory.t)[:-1], iteration_s)     # (the last may be cut by the timeout)
    np.testing.assert_allclose(trajectory.charged_s[decisions], charged_s)
    np.testing.assert_allclose(trajectory.inference_s[decisions], inference_ms / 1000)
    assert run_metrics(trajectory)["brain_frequency_sim_hz"] == pytest.approx(1 / iteration_s, rel=0.05)


def test_extra_latency_is_added_to_the_measured_time():
    trajectory = expert_run(timing="measured", timeout_s=1.0, extra_latency_ms=100.0)
    decisions = trajectory.decisions
    assert np.all(trajectory.charged_s[decisions] >= 0.1) and np.all(trajectory.inference_s[decisions] >= 0.1)
    assert run_metrics(trajectory)["brain_frequency_sim_hz"] <= 10.0
    assert trajectory.meta["measured_inference_ms"] < 100.0       # the real time, without the artificial part


def test_a_slow_brain_reacts_late_and_drives_worse():
    # The expert through nurburgring's first corners, instantly and 200 ms late.
    quick = run_metrics(expert_run("nurburgring", timeout_s=15.0, fixed_inference_ms=0.0))
    slow = run_metrics(expert_run("nurburgring", timeout_s=15.0, fixed_inference_ms=200.0))
    assert slow["brain_frequency_sim_hz"] <= 5.0 < quick["brain_frequency_sim_hz"]
    assert slow["position_deviation_mae_m"] > 2 * quick["position_deviation_mae_m"]


class SlowBrain:
    """A brain that takes 100 ms more per decision than the one it wraps."""

    def __init__(self, brain):
        self._brain = brain

    def __getattr__(self, name):
        return getattr(self._brain, name)

    def act(self, *args, **kwargs):
        time.sleep(0.1)
        return self._brain.act(*args, **kwargs)

    @property
    def last_inference_s(self) -> float:
        return self._brain.last_inference_s + 0.1


def test_lockstep_waits_for_the_brain_whatever_it_costs():
    instant = expert_run(timing="lockstep", timeout_s=2.0)
    with DrivingEnv("simple_circuit", camera=None, timeout_s=2.0) as env:
        late = drive(env, SlowBrain(make_reference_brain("expert")), DriveSettings(timing="lockstep"), seed=0)
    for column in ("t", "x", "y", "speed", "v", "w"):
        np.testing.assert_array_equal(getattr(instant, column), getattr(late, column))
    np.testing.assert_allclose(np.diff(instant.t), 0.05)
    assert np.all(instant.charged_s[instant.decisions] == 0.0)
    assert run_metrics(late)["mean_inference_ms"] >= 100.0 > run_metrics(instant)["mean_inference_ms"]


def test_realtime_follows_the_wall_clock_and_the_world_moves_on_while_the_brain_thinks():
    trajectory = expert_run(timing="realtime", timeout_s=1.5, extra_latency_ms=100.0)
    metrics = run_metrics(trajectory)
    assert trajectory.termination == "timeout"
    assert metrics["brain_frequency_sim_hz"] <= 10.5     # every iteration sleeps 100 ms of wall clock
    assert 0.5 < metrics["real_time_factor"] <= 1.1       # simulated time keeps up with the wall clock
    assert np.all(trajectory.charged_s[trajectory.decisions][:-1] >= 0.09)


def test_fixed_inference_time_belongs_to_the_modes_that_charge_the_brain():
    with pytest.raises(pydantic.ValidationError, match="fixed_inference_ms only means something in the replay and "
                                                       "measured"):
        DriveSettings(timing="realtime", fixed_inference_ms=5.0)
    with pytest.raises(pydantic.ValidationError, match="Input should be 'replay', 'measured', 'lockstep' or "
                                                       "'realtime'"):
        DriveSettings(timing="lazy")


def test_the_explicit_brain_drives_a_stretch_from_the_camera_image():
    frames = []
    with DrivingEnv("simple_circuit", camera=CameraSpec(width=320, height=240), renderer="ground",
                    timeout_s=10.0) as env:
        trajectory = drive(env, make_reference_brain("explicit"), DriveSettings(timing="measured"),
                           on_frame=lambda image, info, command: frames.append((image.shape, command)))
    metrics = run_metrics(trajectory)
    assert trajectory.termination == "timeout" and metrics["off_road_events"] == 0
    assert metrics["completed_distance_m"] > 50 and metrics["position_deviation_mae_m"] < 0.5
    assert len(frames) == len(trajectory.decisions) and frames[0][0] == (240, 320, 3)
    assert frames[5][1] == (trajectory.v[5], trajectory.w[5])     # each image with the command decided on it


def test_a_run_stops_when_the_car_leaves_the_road():
    with DrivingEnv("simple_circuit", camera=None, timeout_s=20.0) as env:
        trajectory = drive(env, Constant(6.0, 0.8), DriveSettings(timing="measured"))
    metrics = run_metrics(trajectory)
    assert trajectory.termination == "off_road" and metrics["off_road_events"] == 1
    assert trajectory.off_road[-1] and not trajectory.off_road[:-1].any()
    assert metrics["lap_completed"] is False and metrics["lap_seconds"] is None


def test_a_camera_brain_needs_a_camera():
    with DrivingEnv("simple_circuit", camera=None) as env, \
            pytest.raises(PilotlabError, match="the explicit brain needs the camera"):
        drive(env, make_reference_brain("explicit"), DriveSettings(timing="measured"))


def test_replay_draws_the_charged_latency_from_the_samples_seeded():
    samples = np.array([10.0, 30.0, 70.0])
    runs = [expert_run(timeout_s=2.0, latency_ms=samples, seed=seed) for seed in (0, 0, 1)]
    charged = [run.inference_s[run.decisions] * 1000 for run in runs]
    assert set(np.round(charged[0], 6)) <= set(samples) and len(set(np.round(charged[0], 6))) > 1
    np.testing.assert_array_equal(charged[0], charged[1])
    assert not np.array_equal(charged[0][:10], charged[2][:10])
    np.testing.assert_allclose(runs[0].brain_s[runs[0].decisions] * 1000, charged[0])   # not this host's clock


def test_replay_needs_samples():
    with pytest.raises(PilotlabError, match="replay timing mode needs latency samples"):
        expert_run(timeout_s=1.0)
