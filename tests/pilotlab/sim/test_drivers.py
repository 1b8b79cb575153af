"""The expert and the explicit brain. The quick tests drive a stretch of road; the `slow` ones drive the
acceptance laps (all five circuits both ways for the expert, simple_circuit both ways for the brain)
and print the figures."""
import time

import numpy as np
import pytest

from pilotlab.circuits import CIRCUITS
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.expert import Expert, ExpertConfig, Swerves, speed_profile
from pilotlab.sim.explicit import ExplicitBrain


def drive_expert(env, options=None, noise=0.0, seed=0):
    obs, info = env.reset(seed=seed, options=options)
    expert = Expert(env.circuit)
    swerves = Swerves(noise, np.random.default_rng(seed), expert)
    infos, started = [info], time.perf_counter()
    while True:
        command = swerves(expert.act(info), info, env.control_period)
        _, _, terminated, truncated, info = env.step(command, render=False)
        infos.append(info)
        if terminated or truncated:
            return infos, time.perf_counter() - started


def drive_brain(env, options=None):
    obs, info = env.reset(seed=0, options=options)
    brain, infos, started = ExplicitBrain(), [info], time.perf_counter()
    while True:
        obs, _, terminated, truncated, info = env.step(brain.act(obs))
        infos.append(info)
        if terminated or truncated:
            return infos, time.perf_counter() - started


def figures(infos, wall):
    distance = np.array([i["distance_to_line"] for i in infos])
    lateral = np.array([i["lateral_offset"] for i in infos])
    last = infos[-1]
    return {"termination": last["termination"], "lap_s": last["sim_time"], "mean_dist_m": distance.mean(),
            "lateral_min_m": lateral.min(), "lateral_max_m": lateral.max(),
            "avg_speed": last["progress"] / last["sim_time"], "wall_s": wall,
            "off_road": any(i["off_road"] for i in infos)}


def test_the_expert_follows_the_line_closely_and_fast():
    with DrivingEnv("nurburgring", camera=None, timeout_s=25.0) as env:  # its first 200 m, the hairpin included
        infos, wall = drive_expert(env)
    result = figures(infos, wall)
    assert result["termination"] == "timeout" and not result["off_road"]
    assert result["mean_dist_m"] < 0.3 and infos[-1]["progress"] > 180


def test_the_speed_profile_brakes_before_corners():
    from pilotlab.circuits.load import get_circuit
    circuit = get_circuit("simple_circuit")
    config = ExpertConfig()
    profile = speed_profile(circuit, config)
    assert profile.max() == config.top_speed and profile.min() >= config.min_speed
    corner = int(np.argmax(np.abs(circuit.curvature)))
    assert profile[corner] < 0.6 * config.top_speed
    spacing = circuit.length / len(profile)
    for back in range(1, 200):  # never faster than braking at the planned rate can undo before the corner
        limit = np.sqrt(profile[corner] ** 2 + 2 * config.braking * back * spacing)
        assert profile[corner - back] <= limit + 1e-9


def test_swerves_take_the_car_off_the_line_and_it_comes_back(stadium_csv):
    with DrivingEnv(stadium_csv, camera=None, laps=2) as env:
        calm, _ = drive_expert(env, noise=0.0)
        noisy, _ = drive_expert(env, noise=0.3, seed=1)
    distances = np.array([i["distance_to_line"] for i in noisy])
    assert distances.max() > 0.5 and distances.max() > 3 * max(i["distance_to_line"] for i in calm)
    assert noisy[-1]["termination"] == "lap_completed" and not any(i["off_road"] for i in noisy)
    first = int(np.argmax(distances > 0.45))
    assert distances[first:].min() < 0.2  # it came back


def test_swerves_are_bounded_by_grip_and_the_road_edge():
    from pilotlab.circuits.load import get_circuit
    expert = Expert(get_circuit("nurburgring", "cw"))
    swerves = Swerves(0.1, np.random.default_rng(0), expert)
    hairpin = float(expert.circuit.arc[np.argmax(expert.bend)])                  # 2 m radius

    def state(s, speed=None, offset=0.0, heading=0.0, road_width=6.0):
        speed = expert.target_speed(s) if speed is None else speed
        return {"s": s, "speed": speed, "lateral_offset": offset, "heading_error": heading, "road_width": road_width}
    straight = 440.0                                                            # 13 m/s, almost straight
    assert swerves.allowed_rate(state(straight)) > 0.55                         # 8 m/s² / 13 m/s, less the bend
    assert swerves.allowed_rate(state(hairpin)) < 0.8                           # the bend takes most of the grip
    assert swerves.allowed_rate(state(hairpin, speed=6.0)) == 0.0               # too fast for it: none at all
    swerves._rate, swerves._left = 0.9, 0.5                                     # mid-swerve...
    command = swerves((10.0, 0.1), state(straight, offset=0.3), 0.05)
    assert command == (10.0, 0.1 + 0.9) and swerves.swerving
    swerves((10.0, 0.1), state(straight, offset=1.2, heading=0.3), 0.05)        # ...heading for the edge: it ends
    assert not swerves.swerving
    swerves._settle = 0.0
    swerves._try_to_start(state(straight, offset=0.8))                          # too far from the line to start
    assert not swerves.swerving


def test_the_explicit_brain_follows_the_red_line_from_the_image():
    camera = CameraSpec(width=160, height=120)
    with DrivingEnv("simple_circuit", camera=camera, renderer="ground", timeout_s=12.0) as env:
        infos, wall = drive_brain(env)  # through the first hairpin
    result = figures(infos, wall)
    assert result["termination"] == "timeout" and not result["off_road"]
    assert infos[-1]["progress"] > 60 and result["mean_dist_m"] < 0.5


@pytest.mark.slow
@pytest.mark.parametrize("direction", ["cw", "ccw"])
@pytest.mark.parametrize("name", CIRCUITS.names())
def test_the_expert_completes_every_circuit(name, direction):
    with DrivingEnv(name, direction=direction, camera=None) as env:
        infos, wall = drive_expert(env)
    result = figures(infos, wall)
    print(f"\nexpert {name} {direction}: " + ", ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}"
                                                    for k, v in result.items()))
    assert result["termination"] == "lap_completed" and not result["off_road"]
    assert result["mean_dist_m"] < 0.3


@pytest.mark.slow
# pybullet's TinyRenderer in one direction only: 16 s a lap (the ground renderer draws the same red line,
# tests/pilotlab/sim/test_render.py; CI's 15 minutes are tight on this machine)
@pytest.mark.parametrize("direction, renderer, size", [("cw", "ground", (640, 480)), ("ccw", "ground", (640, 480)),
                                                       ("ccw", "pybullet", (320, 240))])
def test_the_explicit_brain_completes_simple_circuit(direction, renderer, size):
    camera = CameraSpec(width=size[0], height=size[1])
    with DrivingEnv("simple_circuit", direction=direction, camera=camera, renderer=renderer) as env:
        infos, wall = drive_brain(env)
    result = figures(infos, wall)
    print(f"\nexplicit brain simple_circuit {direction} {renderer} {size}: " + ", ".join(
        f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in result.items()))
    assert result["termination"] == "lap_completed" and not result["off_road"]
