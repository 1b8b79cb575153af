import math

import cv2
import numpy as np
import pybullet as p
import pytest

from pilotlab.circuits.load import get_circuit
from pilotlab.errors import PilotlabError
from pilotlab.sim.camera import GROUND, LINE, ROAD, SKY, WALL, CameraSpec, camera_pose
from pilotlab.sim.car import CarSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.render import GroundRenderer, PybulletRenderer
from pilotlab.sim.world import World

AXLE = CarSpec().wheel_radius


def pose_on(circuit, s, lateral=0.0, heading=0.0, spec=CameraSpec()):
    x, y, yaw = circuit.start_pose(s, lateral)
    return camera_pose(spec, (x, y, AXLE), p.getQuaternionFromEuler([0, 0, yaw + heading]), AXLE)


def red(image):
    return np.all(image == LINE, axis=2)


def iou(a, b):
    return (a & b).sum() / max((a | b).sum(), 1)


@pytest.fixture(scope="module")
def simple():
    circuit = get_circuit("simple_circuit")
    world = World(circuit)
    yield circuit, world
    world.close()


def test_a_frame_looks_like_the_f1_follow_line_view(simple):
    circuit, world = simple
    spec = CameraSpec(width=160, height=120)
    image = PybulletRenderer(world.client, spec).render(*pose_on(circuit, 110.0, spec=spec))  # a straight
    assert image.shape == (120, 160, 3) and image.dtype == np.uint8
    assert np.all(image[:58] == SKY)                       # sky above the horizon (the middle row)
    assert np.all(image[-1, 78:82] == LINE)                # the red line straight ahead, at the bottom
    assert np.all(image[-1, :20] == ROAD) and np.all(image[-1, -20:] == ROAD)  # on a 6 m road
    assert np.all(image[62, :10] == GROUND)                # grass beside the road, far away
    columns = [np.flatnonzero(red(image)[row]).mean() for row in (70, 90, 119)]
    assert np.allclose(columns, 79.5, atol=1.5)            # straight up the middle to the horizon


@pytest.mark.parametrize("size", [(160, 120), (200, 66)])
@pytest.mark.parametrize("s, lateral, heading", [(20.0, 0.0, 0.0), (45.0, 0.8, -0.15), (200.0, -1.5, 0.2),
                                                 (390.0, 0.3, 0.05)])
def test_the_ground_renderer_draws_the_same_red_line_as_pybullet(simple, size, s, lateral, heading):
    circuit, world = simple
    width, height = size
    spec = CameraSpec.crop(width, height) if height == 66 else CameraSpec(width=width, height=height)
    eye, rotation = pose_on(circuit, s, lateral, heading, spec)
    reference = PybulletRenderer(world.client, spec).render(eye, rotation)
    fast = GroundRenderer(circuit, spec).render(eye, rotation)
    assert red(reference).sum() > 50
    assert iou(red(reference), red(fast)) >= 0.8
    assert np.mean(np.any(reference != fast, axis=2)) < 0.05  # and nearly every other pixel too


def test_the_crop_camera_renders_the_lower_half_resized(simple):
    circuit, _ = simple
    full_spec, crop_spec = CameraSpec(width=640, height=480), CameraSpec.crop(200, 66)
    eye, rotation = pose_on(circuit, 30.0, 0.5, 0.1)
    full = GroundRenderer(circuit, full_spec).render(eye, rotation)
    crop = GroundRenderer(circuit, crop_spec).render(eye, rotation)
    lower_half = cv2.resize(full[240:], (200, 66), interpolation=cv2.INTER_AREA)
    assert crop.shape == (66, 200, 3)
    assert iou(red(crop), np.all(np.abs(lower_half.astype(int) - LINE) < 60, axis=2)) >= 0.8


def test_the_horizon_follows_the_camera_pitch():
    spec = CameraSpec(width=64, height=48)
    level = camera_pose(spec, (0, 0, AXLE), (0, 0, 0, 1), AXLE)
    pitched = camera_pose(CameraSpec(width=64, height=48, pitch_deg=10), (0, 0, AXLE), (0, 0, 0, 1), AXLE)
    circuit = get_circuit("simple_circuit")
    rows_of_sky = [np.all(GroundRenderer(circuit, s).render(*pose) == SKY, axis=(1, 2)).sum()
                   for s, pose in ((spec, level), (CameraSpec(width=64, height=48, pitch_deg=10), pitched))]
    assert rows_of_sky[0] == 24
    focal = 32 / math.tan(math.radians(35))
    assert rows_of_sky[1] == pytest.approx(24 - focal * math.tan(math.radians(10)), abs=1)


def test_walls_are_drawn_by_pybullet_and_refused_by_the_ground_renderer(stadium_csv):
    with pytest.raises(PilotlabError, match="cannot show walls"):
        DrivingEnv(stadium_csv, walls=True, renderer="ground")
    with DrivingEnv(stadium_csv, walls=True, renderer="pybullet", camera=CameraSpec(width=80, height=60)) as env:
        obs, _ = env.reset(options={"heading": 0.6})  # looking at the outside wall of the top straight
        assert np.any(np.all(obs == WALL, axis=2))
        for _ in range(30):  # drive into it: the wall stops the car
            obs, _, terminated, _, info = env.step((6.0, 0.0), render=False)
            if terminated:
                break
        assert info["lateral_offset"] < env.circuit.road_width / 2 + 0.6
