"""BehaviorMetrics' simple_circuit, the expert's lap at 20 Hz with a frame every step: real-time factors
with the network's view rendered directly (the online jobs' path), with the full 640×480 frame then
preprocessing, and with no camera. `python -m pytest -m benchmark -s tests/pilotlab/worlds`. Prints,
never asserts timings (the target: ≥ 30× real time for the network view on 2 cores)."""
from __future__ import annotations

import os

import pytest

from pilotlab.sim.expert import BM_EXPERT, ExpertConfig
from tests.pilotlab.test_pipeline_benchmark import expert_lap

pytestmark = pytest.mark.benchmark


def test_bm_world_expert_lap_real_time_factor(bm_assets):
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"\nexpert lap of BM's simple_circuit at 20 Hz, one frame per step (load average {load} on "
          f"{os.cpu_count()} cores):")
    for camera, label in (("view", "network view rendered directly"), ("full", "640x480 frame, then preprocess"),
                          ("none", "no camera")):
        sim, wall, cpu, termination = expert_lap(camera, ExpertConfig(**BM_EXPERT), world="simple_circuit",
                                                 assets=bm_assets)
        print(f"  {label:32s}: real-time factor {sim / wall:6.1f}x wall, {sim / cpu:6.1f}x CPU ({termination})")
