"""The picture `DrivingEnv.render()` returns in render mode "rgb_array": the circuit seen from above
with the path driven since the reset and the car, and the camera view inset in a corner.

Drawn with OpenCV on a map of the whole circuit made once per circuit, so a frame costs a
millisecond or two: a video of a lap (`gymnasium.wrappers.RecordVideo`, with moviepy installed) is cheap.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.sim.camera import GROUND, LINE, ROAD

PATH = (40, 90, 230)
CAR = (250, 210, 20)
INSET_FRACTION = 0.35      # the camera view's width, as a fraction of the map's


class TopDownView:
    """A `size`-pixel map of `circuit` (its longer side), with the path and car drawn per frame."""

    def __init__(self, circuit: Circuit, size: int = 480):
        margin = circuit.road_width + 4.0
        x0, y0, x1, y1 = circuit.bounds(margin)
        self.scale = size / max(x1 - x0, y1 - y0)          # pixels per metre
        self.origin = (x0, y1)                             # the world x, y of the top-left corner
        width, height = (int(math.ceil(extent * self.scale)) for extent in (x1 - x0, y1 - y0))
        self.base = np.empty((height, width, 3), np.uint8)
        self.base[:] = GROUND
        road = max(1, round(circuit.road_width * self.scale))
        centreline = self.pixels(circuit.points)
        cv2.polylines(self.base, [centreline], True, ROAD, road, cv2.LINE_AA)
        cv2.polylines(self.base, [centreline], True, LINE, max(1, road // 12), cv2.LINE_AA)

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        """World x, y (metres) -> integer pixel coordinates, shaped for cv2's polylines."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        columns = (xy[:, 0] - self.origin[0]) * self.scale
        rows = (self.origin[1] - xy[:, 1]) * self.scale
        return np.round(np.stack([columns, rows], axis=1)).astype(np.int32).reshape(-1, 1, 2)

    def draw(self, path: np.ndarray, pose: tuple[float, float, float], length_m: float,
             camera: np.ndarray | None = None) -> np.ndarray:
        """The frame: the map, `path` (x, y rows), the car at `pose` (x, y, yaw) as an arrow
        `length_m` long, and `camera` inset in the top-left corner when given."""
        image = self.base.copy()
        if len(path) > 1:
            cv2.polylines(image, [self.pixels(path)], False, PATH, 2, cv2.LINE_AA)
        x, y, yaw = pose
        half = max(length_m / 2, 4 / self.scale)
        forward, left = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
        centre = np.array([x, y])
        arrow = [centre + forward * half, centre - forward * half + left * half * 0.6,
                 centre - forward * half * 0.5, centre - forward * half - left * half * 0.6]
        cv2.fillPoly(image, [self.pixels(np.array(arrow))], CAR, cv2.LINE_AA)
        if camera is not None:
            inset(image, camera)
        return image


def inset(image: np.ndarray, camera: np.ndarray) -> None:
    """Paste `camera`, scaled to INSET_FRACTION of the width, with a thin frame, into the top-left corner."""
    width = max(8, min(int(image.shape[1] * INSET_FRACTION), image.shape[1] - 2))
    height = min(max(1, round(camera.shape[0] * width / camera.shape[1])), image.shape[0] - 2)
    small = cv2.resize(camera, (width, height), interpolation=cv2.INTER_AREA)
    image[:height + 2, :width + 2] = 255
    image[1:height + 1, 1:width + 1] = small
