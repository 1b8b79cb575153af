"""Driving in a BM-like world: its circuit and camera, its solid walls, both renderers."""
from __future__ import annotations

import numpy as np
import pytest

from pilotlab.data.preprocess import PreprocessConfig
from pilotlab.errors import PilotlabError
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.expert import BM_EXPERT, Expert, ExpertConfig


def test_expert_drives_a_lap_in_the_world(oval_assets):
    with DrivingEnv(world="oval", assets=oval_assets, camera=CameraSpec(), renderer="ground",
                    view=PreprocessConfig()) as env:
        frame, info = env.reset(seed=0)
        assert frame.shape == (66, 200, 3)
        assert env.camera.height_m == pytest.approx(0.104) and env.camera.level
        expert = Expert(env.circuit, ExpertConfig(**BM_EXPERT))
        while True:
            frame, _, terminated, truncated, info = env.step(expert.act(info))
            if terminated or truncated:
                break
    assert info["termination"] == "lap_completed"
    assert env.circuit.road_width == pytest.approx(4.0, abs=0.2)


def test_hitting_a_wall_ends_the_episode(oval_assets):
    """Turning hard left at the start drives across the grass (inside the road check, which is off here)
    into the inner wall."""
    with DrivingEnv(world="oval", assets=oval_assets, camera=None, stop_off_road=False) as env:
        _, info = env.reset(seed=0)
        for _ in range(400):
            _, _, terminated, truncated, info = env.step((3.0, 1.2))
            if terminated or truncated:
                break
    assert info["termination"] == "hit_wall"


def test_the_red_line_is_in_the_camera_frame(oval_assets):
    with DrivingEnv(world="oval", assets=oval_assets, camera=CameraSpec(), renderer="ground") as env:
        frame, _ = env.reset(seed=0)
    red = (frame[..., 0] > 150) & (frame[..., 1] < 80) & (frame[..., 2] < 80)
    assert red[240:].sum() > 1000 and not red[:200].any()   # on the ground ahead, never in the sky
    # the bottom row looks at the ground 0.104 · 320 / 240 m ahead; the camera is 4 cm left of the line
    depth = 0.104 * 320 / 240
    assert np.flatnonzero(red[-1]).mean() == pytest.approx(319.5 + 320 * 0.04 / depth, abs=15)


def test_pybullet_renderer_sees_the_same_line(oval_assets):
    frames = {}
    for renderer in ("ground", "pybullet"):
        with DrivingEnv(world="oval", assets=oval_assets, camera=CameraSpec(), renderer=renderer) as env:
            frames[renderer], _ = env.reset(seed=0, options={"start": 20.0})
    red = {name: (f[..., 0] > 150) & (f[..., 1] < 80) & (f[..., 2] < 80) for name, f in frames.items()}
    overlap = (red["ground"] & red["pybullet"]).sum() / (red["ground"] | red["pybullet"]).sum()
    assert overlap > 0.8


def test_a_world_fixes_its_circuit(oval_assets):
    with pytest.raises(PilotlabError, match="not both"):
        DrivingEnv("simple_circuit", world="oval", assets=oval_assets)
    with DrivingEnv(world="oval", assets=oval_assets, camera=None) as env:
        with pytest.raises(PilotlabError, match="has its own circuit"):
            env.reset(options={"circuit": "montreal"})


def test_gymnasium_make_takes_a_world_without_a_circuit(oval_assets):
    """Outside test: gymnasium.make(..., world=...) said "give a circuit or a world, not both" (the circuit's
    default was simple_circuit) unless circuit=None was given too."""
    import gymnasium
    import pilotlab.sim  # noqa: F401  (registers pilotlab/FollowLine-v0)
    with gymnasium.make("pilotlab/FollowLine-v0", world="oval", assets=str(oval_assets), camera=None,
                        observation="state") as env:
        env.reset(seed=0)
        assert env.unwrapped.circuit.name == "oval"
