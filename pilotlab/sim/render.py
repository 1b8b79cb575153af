"""Two renderers of the camera image: pybullet's TinyRenderer (the reference) and a fast
ground-plane renderer.

pybullet draws the road and line meshes (and walls); the pixels it leaves empty become sky above the
horizon and grass below it, so no triangle is spent on the ground. The ground renderer uses the fact
that the world is flat: the camera image of the ground plane is a homography of a top-down raster of
the road, so one `cv2.warpPerspective` of that raster plus a sky polygon draws the frame (about 20×
faster at 200×66). It cannot draw walls. A test checks that both give the same red line (IoU ≥ 0.8).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.errors import PilotlabError
from pilotlab.sim.bullet import p
from pilotlab.sim.camera import GROUND, LINE, LINE_WIDTH_M, ROAD, SKY, CameraSpec, PixelGrid, sky_polygon

RENDERERS = ("pybullet", "ground")
RASTER_M = 0.05          # ground raster resolution: 5 cm per pixel
_ROAD_LEVEL, _LINE_LEVEL = 127, 255  # raster values: 0 grass, 127 road, 255 line


def fill_polygon(image: np.ndarray, polygon: np.ndarray, colour, mask: np.ndarray | None = None) -> None:
    """Paint `polygon` (pixel coordinates) with `colour`, only where `mask` is true if given."""
    if len(polygon) < 3:
        return
    shift = 4
    points = np.round(polygon * (1 << shift)).astype(np.int32)
    if mask is None:
        cv2.fillPoly(image, [points], colour, lineType=cv2.LINE_8, shift=shift)
        return
    inside = np.zeros(image.shape[:2], np.uint8)
    cv2.fillPoly(inside, [points], 1, lineType=cv2.LINE_8, shift=shift)
    image[(inside == 1) & mask] = colour


class PybulletRenderer:
    """pybullet's CPU TinyRenderer, unshaded, with sky and grass filled in behind the meshes."""

    def __init__(self, client: int, spec: CameraSpec):
        self.client, self.spec = client, spec
        self._projection = spec.gl_projection()

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        spec = self.spec
        forward, up = rotation[2], -rotation[1]
        view = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), up.tolist(), physicsClientId=self.client)
        _, _, rgba, _, _ = p.getCameraImage(
            spec.width, spec.height, view, self._projection, renderer=p.ER_TINY_RENDERER, shadow=0,
            lightAmbientCoeff=1.0, lightDiffuseCoeff=0.0, lightSpecularCoeff=0.0,
            flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=self.client)
        image = np.ascontiguousarray(np.reshape(rgba, (spec.height, spec.width, 4))[:, :, :3], dtype=np.uint8)
        empty = np.all(image == 255, axis=2)  # TinyRenderer's background; no mesh is pure white
        image[empty] = GROUND
        fill_polygon(image, sky_polygon(spec, rotation), SKY, mask=empty)
        return image


_RASTERS: dict[tuple, tuple[np.ndarray, tuple[float, float]]] = {}


def ground_raster(circuit: Circuit, line_width: float, resolution: float) -> tuple[np.ndarray, tuple[float, float]]:
    """Top-down raster of the road (0 grass, 127 road, 255 line) and the world x, y of its top-left
    pixel centre. Cached per circuit (the last few): montreal at 5 cm is about 60 MB."""
    key = (circuit.name, circuit.source, circuit.points[::97].tobytes(), circuit.road_width, line_width, resolution)
    if key not in _RASTERS:
        if len(_RASTERS) >= 3:
            _RASTERS.pop(next(iter(_RASTERS)))
        _RASTERS[key] = _draw_raster(circuit, line_width, resolution)
    return _RASTERS[key]


def _draw_raster(circuit: Circuit, line_width: float, resolution: float) -> tuple[np.ndarray, tuple[float, float]]:
    margin = circuit.road_width + 2.0
    x0, y0, x1, y1 = circuit.bounds(margin)
    raster = np.zeros((int(math.ceil((y1 - y0) / resolution)) + 1, int(math.ceil((x1 - x0) / resolution)) + 1),
                      np.uint8)
    _fill_band(raster, circuit, circuit.road_width / 2, (x0, y1), resolution, _ROAD_LEVEL)
    _paint_line(raster, circuit.points, line_width / 2, (x0, y1), resolution)
    return raster, (x0, y1)


def _fill_band(raster: np.ndarray, circuit: Circuit, half: float, origin: tuple[float, float],
               resolution: float, level: int) -> None:
    """Paint the band within `half` metres of the centreline, one quad between the band's edges per
    segment (quads share edges: no gaps on the outside of bends). cv2 fills a polygon about one pixel
    wider than its outline, hence the half-pixel shrink."""
    left, right = circuit.offset_line(half - resolution / 2), circuit.offset_line(-half + resolution / 2)
    corners = np.stack([left, np.roll(left, -1, axis=0), np.roll(right, -1, axis=0), right], axis=1)
    shift = 4
    pixels = np.stack([(corners[..., 0] - origin[0]) / resolution, (origin[1] - corners[..., 1]) / resolution], axis=2)
    for quad in np.round(pixels * (1 << shift)).astype(np.int32):
        cv2.fillConvexPoly(raster, quad, level, lineType=cv2.LINE_AA, shift=shift)


def _paint_line(raster: np.ndarray, points: np.ndarray, half: float, origin: tuple[float, float],
                resolution: float) -> None:
    """Blend the red line onto the road with exact anti-aliasing: each pixel's level follows its
    distance to the centreline, so the line's edges sit within a fraction of a pixel."""
    starts, ends = points, np.roll(points, -1, axis=0)
    reach = half + resolution
    col0 = np.floor((np.minimum(starts[:, 0], ends[:, 0]) - reach - origin[0]) / resolution).astype(int)
    row0 = np.floor((origin[1] - np.maximum(starts[:, 1], ends[:, 1]) - reach) / resolution).astype(int)
    box = int(np.ceil((np.abs(ends - starts).max() + 2 * reach) / resolution)) + 2
    grid_r, grid_c = np.divmod(np.arange(box * box), box)
    rows, cols = row0[:, None] + grid_r[None], col0[:, None] + grid_c[None]       # [segments, box²]
    x, y = origin[0] + cols * resolution, origin[1] - rows * resolution
    along = ends - starts
    t = ((x - starts[:, :1]) * along[:, :1] + (y - starts[:, 1:]) * along[:, 1:]) / np.sum(along**2, axis=1)[:, None]
    t = np.clip(t, 0.0, 1.0)
    distance = np.hypot(x - starts[:, :1] - t * along[:, :1], y - starts[:, 1:] - t * along[:, 1:])
    flat = (rows * raster.shape[1] + cols).ravel()
    order = np.argsort(flat, kind="stable")
    flat, distance = flat[order], distance.ravel()[order]
    first = np.flatnonzero(np.r_[True, flat[1:] != flat[:-1]])
    nearest = np.minimum.reduceat(distance, first)
    coverage = np.clip((half - nearest) / resolution + 0.5, 0.0, 1.0)
    pixels = flat[first][coverage > 0]
    levels = _ROAD_LEVEL + (_LINE_LEVEL - _ROAD_LEVEL) * coverage[coverage > 0]
    raster.ravel()[pixels] = np.round(levels).astype(np.uint8)


def _level_palette() -> np.ndarray:
    """256 RGB colours for the raster levels, split at the midpoints between grass, road and line.

    Bilinear sampling of the 5 cm raster is a ramp across each edge whose midpoint is the true edge,
    so thresholding there gives sharp edges in the right place (TinyRenderer does not blur either).
    `cv2.applyColorMap` only looks colours up, so an RGB palette gives RGB pixels (no BGR round trip)."""
    levels = np.arange(256)
    rgb = np.where((levels < (_ROAD_LEVEL + 1) // 2)[:, None], GROUND,
                   np.where((levels < (_ROAD_LEVEL + _LINE_LEVEL + 1) // 2)[:, None], ROAD, LINE))
    return rgb.astype(np.uint8).reshape(256, 1, 3)


class GroundRenderer:
    """A homography of the circuit's top-down raster onto the image, sky above the horizon.

    With a `grid`, it draws only the grid's samples of the full frame (see PixelGrid): the network's
    view renders one sample per block of the frame that preprocessing would average (pilotlab.sim.view)."""

    def __init__(self, circuit: Circuit, spec: CameraSpec, line_width: float = LINE_WIDTH_M,
                 resolution: float = RASTER_M, grid: PixelGrid | None = None):
        self.raster, (x0, y1) = ground_raster(circuit, line_width, resolution)
        self.spec, self.grid = spec, grid or PixelGrid.full(spec)
        self._intrinsics = spec.intrinsics() if grid is None else grid.intrinsics(spec)
        self._inverse = np.linalg.inv(self._intrinsics)
        # raster pixel (col, row, 1) -> world (x, y, 1)
        self._raster_to_world = np.array([[resolution, 0, x0], [0, -resolution, y1], [0, 0, 1]])
        self._palette = _level_palette()

    def render(self, eye: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        ground_to_camera = np.stack([rotation[:, 0], rotation[:, 1], -rotation @ eye], axis=1)
        homography = self._intrinsics @ ground_to_camera @ self._raster_to_world
        levels = cv2.warpPerspective(self.raster, homography, self.grid.size, flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        image = cv2.applyColorMap(levels, self._palette)
        fill_polygon(image, sky_polygon(self.spec, rotation, self._inverse, self.grid.size), SKY)
        return image


def check_renderer(name: str, walls: bool) -> str:
    if name not in RENDERERS:
        raise PilotlabError(f"unknown renderer {name!r}; use one of: {', '.join(RENDERERS)}")
    if name == "ground" and walls:
        raise PilotlabError("the ground renderer draws only the flat ground and cannot show walls; "
                            "use renderer 'pybullet' with walls, or turn walls off")
    return name
