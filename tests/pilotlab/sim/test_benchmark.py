"""Closed-loop speed of the simulator: run with `pytest -m benchmark -s tests/pilotlab/sim/test_benchmark.py`.

Prints frames per second of the closed loop (expert at 20 Hz, one camera frame per control step) at the
default 640×480 camera and at the network's 200×66 crop, with pybullet's TinyRenderer and the
ground-plane renderer, and the real-time factor of a whole montreal lap. Never asserts timings.
"""
import time

import pytest

from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.expert import Expert

CAMERAS = {"640x480": CameraSpec(), "200x66 crop": CameraSpec.crop(200, 66)}


def closed_loop(circuit, camera, renderer, max_steps=None):
    """(steps, simulated seconds, wall seconds, termination) of the expert driving with the camera on."""
    with DrivingEnv(circuit, camera=camera, renderer=renderer) as env:
        obs, info = env.reset(seed=0)
        expert = Expert(env.circuit)
        env.step(expert.act(info))  # warm up: builds the ground raster outside the timing
        obs, info = env.reset(seed=0)
        steps, started = 0, time.perf_counter()
        while max_steps is None or steps < max_steps:
            obs, _, terminated, truncated, info = env.step(expert.act(info))
            steps += 1
            if terminated or truncated:
                break
        return steps, info["sim_time"], time.perf_counter() - started, info["termination"]


@pytest.mark.benchmark
def test_closed_loop_frames_per_second():
    print("\nclosed loop on simple_circuit, expert at 20 Hz, a frame rendered every step")
    fps = {}
    for renderer in ("pybullet", "ground"):
        for label, camera in CAMERAS.items():
            budget = 60 if (renderer, label) == ("pybullet", "640x480") else 400
            steps, sim, wall, _ = closed_loop("simple_circuit", camera, renderer, max_steps=budget)
            fps[renderer, label] = steps / wall
            print(f"  {renderer:8s} {label:12s}: {steps / wall:7.1f} frames/s, real-time factor {sim / wall:6.1f}x")
    for label in CAMERAS:
        print(f"  ground renderer vs pybullet at {label}: {fps['ground', label] / fps['pybullet', label]:.1f}x faster")


@pytest.mark.benchmark
@pytest.mark.parametrize("renderer", ["ground", "pybullet"])
def test_montreal_lap_real_time_factor(renderer):
    steps, sim, wall, termination = closed_loop("montreal", CameraSpec.crop(200, 66), renderer)
    print(f"\nmontreal lap at the 200x66 crop, {renderer} renderer: {termination} after {sim:.1f} s simulated "
          f"in {wall:.1f} s wall ({steps} frames, {steps / wall:.0f} frames/s): real-time factor {sim / wall:.1f}x "
          f"(target >= 10x; BehaviorMetrics on Gazebo: ~0.5x)")
    assert termination == "lap_completed"


@pytest.mark.benchmark
@pytest.mark.parametrize("compressed", [None, "png", "jpeg"])
def test_recording_a_lap_of_simple_circuit_at_640x480(tmp_path, compressed):
    from pilotlab.sim.record import RecordSpec, record
    summary = record(RecordSpec(circuit="simple_circuit", compressed=compressed), tmp_path / "lap")
    print(f"\nrecording a lap of simple_circuit at 640x480, 10 Hz, {compressed or 'raw rgb8'}: "
          f"{summary.frames} frames, {summary.sim_seconds:.1f} s simulated in {summary.wall_seconds:.1f} s wall, "
          f"{summary.bytes / 1e6:.1f} MB")
    assert summary.termination == "lap_completed"
