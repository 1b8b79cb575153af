"""BehaviorMetrics' simple_circuit, the expert's lap at 20 Hz with a frame every step: real-time factors
with the network's view rendered directly (the online jobs' path), with the full 640×480 frame then
preprocessing, and with no camera. `python -m pytest -m benchmark -s tests/pilotlab/worlds`. Prints,
never asserts timings (the target: ≥ 30× real time for the network view on 2 cores)."""
from __future__ import annotations

import os
import time

import pytest

pytestmark = pytest.mark.benchmark


def expert_lap(assets, camera: str) -> tuple[float, float, float, str]:
    """(simulated s, wall s, CPU s, termination) of the expert's lap, a frame every step."""
    import cv2

    from pilotlab.data.preprocess import PreprocessConfig, preprocess
    from pilotlab.sim.camera import CameraSpec
    from pilotlab.sim.env import DrivingEnv
    from pilotlab.sim.expert import BM_EXPERT, Expert, ExpertConfig
    cv2.setNumThreads(1)
    config = PreprocessConfig()
    with DrivingEnv(world="simple_circuit", assets=assets, camera=None if camera == "none" else CameraSpec(),
                    renderer="ground", view=config if camera == "view" else None) as env:
        obs, info = env.reset(seed=0)                     # the world is converted (or read) outside the timing
        expert = Expert(env.circuit, ExpertConfig(**BM_EXPERT))
        wall, cpu = time.perf_counter(), time.process_time()
        while True:
            obs, _, terminated, truncated, info = env.step(expert.act(info), render=camera != "none")
            if camera == "full":
                preprocess(obs, config)                   # what a network brain does with a full frame
            if terminated or truncated:
                break
        return info["sim_time"], time.perf_counter() - wall, time.process_time() - cpu, info["termination"]


def test_bm_world_expert_lap_real_time_factor(bm_assets):
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"\nexpert lap of BM's simple_circuit at 20 Hz, one frame per step (load average {load} on "
          f"{os.cpu_count()} cores):")
    for camera, label in (("view", "network view rendered directly"), ("full", "640x480 frame, then preprocess"),
                          ("none", "no camera")):
        sim, wall, cpu, termination = expert_lap(bm_assets, camera)
        print(f"  {label:32s}: real-time factor {sim / wall:6.1f}x wall, {sim / cpu:6.1f}x CPU ({termination})")
