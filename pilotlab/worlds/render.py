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
        self._intrinsics = spec.intrinsics() if grid is None else grid.intrinsics(spec)
        self._to_world = world.grid.to_world()
        self._sharp = [(layer, Grid(**layer["grid"]).to_world(), distance)
                       for layer, distance in zip(world.sharp, world.distances)]
        self._sky_rows, self._sky = self._sky_image()
        self._solids = SolidCells(world.solid_triangles, world.solid_colours)

    def _sky_image(self) -> tuple[int, np.ndarray]:
        """Rows above the far clip line (the ground there is beyond `far_m`) and the sky they show."""
        width, height = self.grid.size
        k = self._intrinsics
        clip_row = k[1, 2] + k[1, 1] * self.spec.height_m / self.spec.far_m   # v where ground depth = far
        rows = int(np.clip(np.ceil(clip_row - 1e-9), 0, height))
        v = (np.arange(height) - k[1, 2]) / k[1, 1]          # tan of the angle below the horizon
        t = np.clip(-v / 0.6, 0.0, 1.0)[:, None]
        colours = (1 - t) * np.array(SKY_HORIZON) + t * np.array(SKY_ZENITH)
        return rows, np.repeat(colours[:, None, :], width, axis=1).astype(np.uint8)

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


class SolidCells:
    """Wall triangles bucketed by cell; each frame paints those within the far clip, clipped to the
    view between the near and far planes, farthest first."""

    def __init__(self, triangles: np.ndarray, colours: np.ndarray):
        self.triangles, self.colours = triangles, colours
        self.cells: dict[tuple[int, int], np.ndarray] = {}
        if len(triangles):
            lows = np.floor(triangles[:, :, :2].min(axis=1) / CELL_M).astype(int)
            highs = np.floor(triangles[:, :, :2].max(axis=1) / CELL_M).astype(int)
            for index, (low, high) in enumerate(zip(lows, highs)):
                for cx in range(low[0], high[0] + 1):
                    for cy in range(low[1], high[1] + 1):
                        self.cells.setdefault((cx, cy), []).append(index)
            self.cells = {key: np.array(value) for key, value in self.cells.items()}

    def near(self, eye: np.ndarray, reach: float) -> np.ndarray:
        low = np.floor((eye[:2] - reach) / CELL_M).astype(int)
        high = np.floor((eye[:2] + reach) / CELL_M).astype(int)
        found = [self.cells.get((cx, cy)) for cx in range(low[0], high[0] + 1) for cy in range(low[1], high[1] + 1)]
        found = [f for f in found if f is not None]
        return np.unique(np.concatenate(found)) if found else np.zeros(0, int)

    def paint(self, image: np.ndarray, eye: np.ndarray, rotation: np.ndarray, intrinsics: np.ndarray,
              spec: CameraSpec) -> None:
        chosen = self.near(eye, spec.far_m)
        if not len(chosen):
            return
        camera = (self.triangles[chosen] - eye) @ rotation.T          # (n, 3, 3) camera coordinates
        depth = camera[:, :, 2]
        visible = (depth.max(axis=1) > spec.near_m) & (depth.min(axis=1) < spec.far_m)
        # outside the horizontal field of view on one side, entirely: skip
        slope = np.abs(intrinsics[0, 2] / intrinsics[0, 0]) + 1.0
        visible &= ~np.all(camera[:, :, 0] > slope * np.maximum(depth, 0) + 1e-3, axis=1)
        visible &= ~np.all(camera[:, :, 0] < -slope * np.maximum(depth, 0) - 1e-3, axis=1)
        order = np.flatnonzero(visible)
        order = order[np.argsort(-depth[order].mean(axis=1))]
        for index in order:
            polygon = clip_depth(camera[index], spec.near_m, spec.far_m)
            if len(polygon) >= 3:
                pixels = polygon @ intrinsics.T
                pixels = pixels[:, :2] / pixels[:, 2:]
                points = np.round(pixels * 16).astype(np.int32)
                cv2.fillPoly(image, [points], self.colours[chosen[index]].tolist(), lineType=cv2.LINE_8, shift=4)


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
