"""The camera image of a BM world, fast: ground by homography, walls as projected polygons.

The ground of BM's worlds is flat (every layer lies within millimetres of z = 0), so its camera image is
a homography of the top-down colour raster (pilotlab.worlds.raster), one `cv2.warpPerspective`; each
flat-coloured layer (the line, marks) is warped from its signed-distance raster and painted inside
its edge, at its own height, so its edges are sharp and in place. Then the sky above the
far clip line (a level camera: that line is a fixed row), and the solids (walls) within the far clip,
clipped to the view, painted far to near. About 1 ms for the network's view (pilotlab.sim.view's grid).

`BulletWorldRenderer` draws the same world with pybullet's TinyRenderer from meshes (the reference;
pilotlab.worlds.bullet), slow but independent: tests compare the two.
"""
from __future__ import annotations

import cv2
import numpy as np

from pilotlab.errors import PilotlabError
from pilotlab.sim.camera import CameraSpec, PixelGrid
from pilotlab.worlds.raster import Grid
from pilotlab.worlds.world import VOID, BMWorld

SKY_HORIZON, SKY_ZENITH = (205, 218, 232), (118, 158, 212)   # Gazebo's sky, without its clouds
CELL_M = 15.0               # solids are bucketed in cells this wide, for culling


class WorldRenderer:
    def __init__(self, world: BMWorld, spec: CameraSpec, grid: PixelGrid | None = None):
        if not spec.level:
            raise PilotlabError("the BM world renderer needs a level camera (CameraSpec(level=True), as "
                                "bm_camera() is): its horizon must stay a fixed row")
        self.world, self.spec, self.grid = world, spec, grid or PixelGrid.full(spec)
        # Gazebo's camera is an ideal pinhole (TinyRenderer's half-pixel offsets are its own)
        self._intrinsics = spec.pinhole_intrinsics() if grid is None else grid.intrinsics(spec, pinhole=True)
        self._to_world = world.grid.to_world()
        self._sharp = [(layer, Grid(**layer["grid"]).to_world(), distance)
                       for layer, distance in zip(world.sharp, world.distances)]
        self._sky_rows, self._sky = sky_image(spec, self._intrinsics, self.grid.size)
        self._solids = SolidCells(world.solid_triangles, world.solid_colours)

    def _homography(self, eye: np.ndarray, rotation: np.ndarray, height: float, to_world=None) -> np.ndarray:
        plane = np.stack([rotation[:, 0], rotation[:, 1], rotation[:, 2] * height - rotation @ eye], axis=1)
        return self._intrinsics @ plane @ (self._to_world if to_world is None else to_world)

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        size = self.grid.size
        image = cv2.warpPerspective(self.world.colour, self._homography(eye, rotation, 0.0), size,
                                    flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=VOID)
        for layer, to_world, distance in self._sharp:
            warped = cv2.warpPerspective(distance, self._homography(eye, rotation, layer["height"], to_world), size,
                                         flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            image[warped >= 128] = layer["colour"]
        image[:self._sky_rows] = self._sky[:self._sky_rows]
        self._solids.paint(image, eye, rotation, self._intrinsics, self.spec)
        return image


def sky_image(spec: CameraSpec, intrinsics: np.ndarray, size: tuple[int, int]) -> tuple[int, np.ndarray]:
    """The rows above the far clip line of a level camera (the ground there lies beyond `far_m`, so
    Gazebo shows its sky) and the sky's colours (a gradient from the horizon up) for the whole image."""
    width, height = size
    clip_row = intrinsics[1, 2] + intrinsics[1, 1] * spec.height_m / spec.far_m
    rows = int(np.clip(np.ceil(clip_row - 1e-9), 0, height))
    below_horizon = (np.arange(height) - intrinsics[1, 2]) / intrinsics[1, 1]
    t = np.clip(-below_horizon / 0.6, 0.0, 1.0)[:, None]
    colours = (1 - t) * np.array(SKY_HORIZON) + t * np.array(SKY_ZENITH)
    return rows, np.repeat(colours[:, None, :], width, axis=1).astype(np.uint8)


class BulletWorldRenderer:
    """pybullet's TinyRenderer over the world's meshes (pilotlab.worlds.bullet.add_visuals must have put
    them in `client`), unshaded (the meshes carry their light); where no mesh is drawn, the sky above the
    far clip line and Gazebo's background below it, as the fast renderer."""

    def __init__(self, client: int, spec: CameraSpec):
        if not spec.level:
            raise PilotlabError("the BM world renderers need a level camera (bm_camera())")
        self.client, self.spec = client, spec
        # TinyRenderer samples pixel i at window coordinate i, not i + 0.5 (CameraSpec.intrinsics): moving
        # the window half a pixel makes its image the ideal pinhole's, as Gazebo's (measured: IoU of the
        # red line with an exact projection 0.66 -> 0.84 at its worst pose)
        self._projection = spec.gl_projection((0.5, -0.5))
        self._sky_rows, self._sky = sky_image(spec, spec.intrinsics(), spec.size)

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        from pilotlab.sim.bullet import p
        spec = self.spec
        forward, up = rotation[2], -rotation[1]
        view = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), up.tolist(), physicsClientId=self.client)
        _, _, rgba, _, segmentation = p.getCameraImage(
            spec.width, spec.height, view, self._projection, renderer=p.ER_TINY_RENDERER, shadow=0,
            lightAmbientCoeff=1.0, lightDiffuseCoeff=0.0, lightSpecularCoeff=0.0, physicsClientId=self.client)
        image = np.ascontiguousarray(np.reshape(rgba, (spec.height, spec.width, 4))[:, :, :3], dtype=np.uint8)
        empty = np.reshape(segmentation, (spec.height, spec.width)) < 0
        background = np.empty_like(image)
        background[:] = VOID
        background[:self._sky_rows] = self._sky[:self._sky_rows]
        image[empty] = background[empty]
        return image


class SolidCells:
    """Wall triangles bucketed by cell; each frame paints those within the far clip that face the camera
    (SketchUp exports each side of a wall as its own triangles, in the side's colour), clipped to the
    view between the near and far planes, farthest first."""

    def __init__(self, triangles: np.ndarray, colours: np.ndarray):
        # quads where two triangles make one (SketchUp's walls): half the polygons to paint
        self.polygons, self.colours = merge_quads(triangles, colours)
        polygons = self.polygons
        self.normals = np.cross(polygons[:, 1] - polygons[:, 0], polygons[:, 2] - polygons[:, 0]) if len(polygons) \
            else np.zeros((0, 3))
        cells: dict[tuple[int, int], list[int]] = {}
        if len(polygons):
            lows = np.floor(polygons[:, :, :2].min(axis=1) / CELL_M).astype(int)
            highs = np.floor(polygons[:, :, :2].max(axis=1) / CELL_M).astype(int)
            for index, (low, high) in enumerate(zip(lows, highs)):
                for cx in range(low[0], high[0] + 1):
                    for cy in range(low[1], high[1] + 1):
                        cells.setdefault((cx, cy), []).append(index)
        self.cells = {key: np.array(value) for key, value in cells.items()}

    def near(self, eye: np.ndarray, reach: float) -> np.ndarray:
        low = np.floor((eye[:2] - reach) / CELL_M).astype(int)
        high = np.floor((eye[:2] + reach) / CELL_M).astype(int)
        chosen = np.zeros(len(self.polygons), bool)
        for cx in range(low[0], high[0] + 1):
            for cy in range(low[1], high[1] + 1):
                found = self.cells.get((cx, cy))
                if found is not None:
                    chosen[found] = True
        return np.flatnonzero(chosen)

    def paint(self, image: np.ndarray, eye: np.ndarray, rotation: np.ndarray, intrinsics: np.ndarray,
              spec: CameraSpec) -> None:
        chosen = self.near(eye, spec.far_m)
        if not len(chosen):
            return
        facing = np.einsum("ij,ij->i", self.normals[chosen], eye - self.polygons[chosen, 0]) > 0
        chosen = chosen[facing]
        camera = (self.polygons[chosen] - eye) @ rotation.T           # (n, 4, 3) camera coordinates
        depth = camera[:, :, 2]
        visible = (depth.max(axis=1) > spec.near_m) & (depth.min(axis=1) < spec.far_m)
        slope = abs(intrinsics[0, 2] / intrinsics[0, 0]) + 1.0           # beyond the horizontal view: skip
        positive = np.maximum(depth, 0)
        visible &= ~np.all(camera[:, :, 0] > slope * positive + 1e-3, axis=1)
        visible &= ~np.all(camera[:, :, 0] < -slope * positive - 1e-3, axis=1)
        order = np.flatnonzero(visible)
        order = order[np.argsort(-depth[order].mean(axis=1))]
        inside = (depth[order].min(axis=1) >= spec.near_m) & (depth[order].max(axis=1) <= spec.far_m)
        projected = camera[order] @ intrinsics.T
        depths = np.where(inside[:, None, None], projected[:, :, 2:], 1.0)   # the others are clipped below
        pixels = np.round(np.where(inside[:, None, None], projected[:, :, :2] / depths, 0) * 16).astype(np.int32)
        colours = self.colours[chosen[order]].tolist()
        for k, index in enumerate(order):
            if inside[k]:
                points = pixels[k]
            else:
                polygon = clip_depth(camera[index], spec.near_m, spec.far_m)
                if len(polygon) < 3:
                    continue
                projected_polygon = polygon @ intrinsics.T
                points = np.round(projected_polygon[:, :2] / projected_polygon[:, 2:] * 16).astype(np.int32)
            cv2.fillConvexPoly(image, points, colours[k], lineType=cv2.LINE_8, shift=4)


def merge_quads(triangles: np.ndarray, colours: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 4, 3) convex polygons: each pair of consecutive triangles of one colour that share an edge and
    a plane becomes a quad; a triangle left alone repeats its last corner."""
    polygons, kept, i = [], [], 0
    while i < len(triangles):
        quad = _quad(triangles[i], triangles[i + 1]) if i + 1 < len(triangles) and \
            np.array_equal(colours[i], colours[i + 1]) else None
        polygons.append(quad if quad is not None else np.vstack([triangles[i], triangles[i][2:]]))
        kept.append(colours[i])
        i += 2 if quad is not None else 1
    if not polygons:
        return np.zeros((0, 4, 3)), np.zeros((0, 3), np.uint8)
    return np.array(polygons), np.array(kept, dtype=np.uint8)


def _quad(first: np.ndarray, second: np.ndarray, tolerance: float = 1e-6) -> np.ndarray | None:
    shared = [(i, j) for i in range(3) for j in range(3) if np.abs(first[i] - second[j]).max() < tolerance]
    if len(shared) != 2:
        return None
    normal_a = np.cross(first[1] - first[0], first[2] - first[0])
    normal_b = np.cross(second[1] - second[0], second[2] - second[0])
    if np.linalg.norm(np.cross(normal_a, normal_b)) > 1e-6 * np.linalg.norm(normal_a) * np.linalg.norm(normal_b) \
            or np.dot(normal_a, normal_b) <= 0:
        return None
    lone_a = next(i for i in range(3) if i not in (a for a, _ in shared))
    lone_b = next(j for j in range(3) if j not in (b for _, b in shared))
    # walk the first triangle from its lone corner; the second's lone corner goes between the shared ones
    quad = [first[lone_a], first[(lone_a + 1) % 3], second[lone_b], first[(lone_a + 2) % 3]]
    corners = np.array(quad)
    turns = [np.dot(np.cross(corners[k + 1 & 3] - corners[k], corners[k + 2 & 3] - corners[k + 1 & 3]), normal_a)
             for k in range(4)]
    return corners if all(t > 0 for t in turns) else None


def clip_depth(polygon: np.ndarray, near: float, far: float) -> np.ndarray:
    """The part of a camera-frame polygon with near <= z <= far (Sutherland-Hodgman on two planes)."""
    for plane, keep_above in ((near, True), (far, False)):
        kept = []
        count = len(polygon)
        for i in range(count):
            a, b = polygon[i], polygon[(i + 1) % count]
            inside_a = a[2] >= plane if keep_above else a[2] <= plane
            inside_b = b[2] >= plane if keep_above else b[2] <= plane
            if inside_a:
                kept.append(a)
            if inside_a != inside_b:
                t = (plane - a[2]) / (b[2] - a[2])
                kept.append(a + t * (b - a))
        polygon = np.array(kept)
        if len(polygon) < 3:
            return polygon
    return polygon
