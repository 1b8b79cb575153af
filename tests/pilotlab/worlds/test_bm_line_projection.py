"""The acceptance check of BM's world in pilotlab: the red line of BM's simple_circuit mesh, projected
through a pinhole camera written here (BM's F1 camera: 640×480, horizontal FOV 1.57 rad, at (0.45, 0.04,
0.10) m on a car spawned 4 mm up, level), must cover the same pixels as the rendered frame's red ones in
the lower half, at poses along BM's perfect lap. The triangles are read with trimesh directly (with the
file's inch unit applied here), not through pilotlab's importer, and the projection knows nothing of the
renderers."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest
import trimesh

from pilotlab.circuits.load import get_circuit
from pilotlab.sim.camera import camera_pose
from pilotlab.worlds import load_world
from pilotlab.worlds.render import WorldRenderer

WIDTH, HEIGHT, HFOV = 640, 480, 1.57
MOUNT = np.array([0.45, 0.04, 0.10 + 0.004])
POSES = 12


def red_line_triangles(assets) -> np.ndarray:
    path = assets / "models" / "simple_circuit" / "meshes" / "simple_line.dae"
    unit = ET.parse(path).getroot().find("{http://www.collada.org/2005/11/COLLADASchema}asset/"
                                         "{http://www.collada.org/2005/11/COLLADASchema}unit")
    metres = float(unit.get("meter"))
    triangles = []
    for mesh in trimesh.load(str(path), force="scene").dump(concatenate=False):
        colour = tuple(int(c) for c in mesh.visual.material.baseColorFactor[:3])
        up = mesh.face_normals[:, 2] > 0.5
        if colour == (255, 0, 0) and up.any():
            triangles.append(mesh.vertices[mesh.faces[up]] * metres)
    return np.concatenate(triangles)


def clip(polygon: list[np.ndarray], depth_axis: int, low: float, high: float) -> list[np.ndarray]:
    """The part of a polygon (points as [depth, right, down]) between two depth planes."""
    for limit, keep in ((low, lambda d: d >= low), (high, lambda d: d <= high)):
        kept = []
        for a, b in zip(polygon, polygon[1:] + polygon[:1]):
            if keep(a[depth_axis]):
                kept.append(a)
            if keep(a[depth_axis]) != keep(b[depth_axis]):
                kept.append(a + (limit - a[depth_axis]) / (b[depth_axis] - a[depth_axis]) * (b - a))
        polygon = kept
    return polygon


def projected_mask(triangles: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    """Pinhole projection (OpenCV pixel centres) of the triangles seen from the car at (x, y, yaw),
    clipped to the camera's 0.1-15 m depth range."""
    c, s = math.cos(yaw), math.sin(yaw)
    eye = np.array([x + c * MOUNT[0] - s * MOUNT[1], y + s * MOUNT[0] + c * MOUNT[1], MOUNT[2]])
    forward, left = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    relative = triangles - eye
    camera = np.stack([relative @ forward, -(relative @ left), -relative[..., 2]], axis=-1)  # depth, right, down
    near = (camera[..., 0].max(axis=1) > 0.1) & (camera[..., 0].min(axis=1) < 15)
    focal = (WIDTH / 2) / math.tan(HFOV / 2)
    mask = np.zeros((HEIGHT, WIDTH), np.uint8)
    for triangle in camera[near]:
        polygon = np.array(clip(list(triangle), 0, 0.1, 15.0))
        if len(polygon) < 3:
            continue
        u = focal * polygon[:, 1] / polygon[:, 0] + (WIDTH - 1) / 2
        v = focal * polygon[:, 2] / polygon[:, 0] + (HEIGHT - 1) / 2
        points = np.round(np.stack([u, v], axis=1) * 16).astype(np.int32)
        cv2.fillConvexPoly(mask, points, 1, lineType=cv2.LINE_8, shift=4)
    return mask.astype(bool)


def rendered_red(renderer, x: float, y: float, yaw: float) -> np.ndarray:
    camera = renderer.spec
    eye, rotation = camera_pose(camera, (x, y, 0.0), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)), 0.0)
    image = renderer.render(eye, rotation).astype(int)
    return (image[..., 0] > 150) & (image[..., 1] < 80) & (image[..., 2] < 80)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def lap_poses(count: int):
    """Poses along BM's perfect lap (the centreline, driven clockwise), a little off it as a car drives."""
    circuit = get_circuit("simple_circuit")
    rng = np.random.default_rng(0)
    for s in np.linspace(0, circuit.length, count, endpoint=False):
        x, y, yaw = circuit.start_pose(float(s), lateral=float(rng.uniform(-0.3, 0.3)))
        yield x, y, yaw + float(rng.uniform(-0.1, 0.1))


def test_red_line_projection_matches_the_fast_renderer(bm_assets):
    world = load_world("simple_circuit", bm_assets)
    renderer = WorldRenderer(world, world.camera())
    triangles = red_line_triangles(bm_assets)
    scores = []
    for x, y, yaw in lap_poses(POSES):
        expected = projected_mask(triangles, x, y, yaw)[HEIGHT // 2:]
        scores.append(iou(expected, rendered_red(renderer, x, y, yaw)[HEIGHT // 2:]))
        assert expected.sum() > 500, "the line should be in view at every pose"
    print("IoU per pose:", " ".join(f"{score:.3f}" for score in scores))
    assert min(scores) >= 0.8, scores


@pytest.mark.slow
def test_red_line_projection_matches_pybullet(bm_assets):
    from pilotlab.sim.bullet import p
    from pilotlab.worlds.bullet import add_visuals
    from pilotlab.worlds.render import BulletWorldRenderer
    world = load_world("simple_circuit", bm_assets)
    client = p.connect(p.DIRECT)
    try:
        add_visuals(client, world)
        renderer = BulletWorldRenderer(client, world.camera())
        triangles = red_line_triangles(bm_assets)
        scores = [iou(projected_mask(triangles, x, y, yaw)[HEIGHT // 2:],
                      rendered_red(renderer, x, y, yaw)[HEIGHT // 2:]) for x, y, yaw in lap_poses(POSES)]
    finally:
        p.disconnect(physicsClientId=client)
    print("IoU per pose:", " ".join(f"{score:.3f}" for score in scores))
    assert min(scores) >= 0.8, scores
