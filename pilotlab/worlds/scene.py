"""A BM world's meshes sorted the way a car sees them: ground layers (flat, facing up, at road level,
one per look: grass, asphalt, the line...) painted from the lowest up, and solids (walls, posts)
standing on them."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pilotlab.worlds.collada import Part

GROUND_MAX_Z_M = 0.05       # a face lower than this and facing up is painted on the ground
UP_NORMAL_Z = 0.5           # |normal z| above this: the face is flat (ground), below: it stands (solid)
MIN_LAYER_AREA_M2 = 0.01


@dataclass(frozen=True)
class Layer:
    """Flat faces of one look lying on the ground: 2-D triangles (n, 3, 2) in world metres."""
    triangles: np.ndarray = field(repr=False)
    colour: tuple[int, int, int]
    height: float
    area: float
    texture: np.ndarray | None = field(default=None, repr=False)
    uv_map: np.ndarray | None = field(default=None, repr=False)   # 2×3: (x, y, 1) -> texture (u, v)
    name: str = ""


@dataclass(frozen=True)
class Solid:
    """Faces that stand up (walls, posts): 3-D triangles (n, 3, 3) and their RGB."""
    triangles: np.ndarray = field(repr=False)
    colour: tuple[int, int, int]


def normals(triangles: np.ndarray) -> np.ndarray:
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    return np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)


def triangle_areas(flat: np.ndarray) -> np.ndarray:
    """Signed areas of 2-D triangles (n, 3, 2): + counter-clockwise."""
    a, b = flat[:, 1] - flat[:, 0], flat[:, 2] - flat[:, 0]
    return (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / 2


def split_scene(parts: list[Part]) -> tuple[list[Layer], list[Solid]]:
    """Ground layers in painting order (lowest first; at one height the larger first) and solids."""
    layers, solids = [], []
    for part in parts:
        normal_z = normals(part.triangles)[:, 2]
        top = part.triangles[:, :, 2].max(axis=1)
        flat = (normal_z > UP_NORMAL_Z) & (top < GROUND_MAX_Z_M)
        standing = (np.abs(normal_z) <= UP_NORMAL_Z) | ((normal_z > UP_NORMAL_Z) & (top >= GROUND_MAX_Z_M))
        layer = _layer(part, flat)
        if layer is not None:
            layers.append(layer)
        if standing.any():
            solids.append(Solid(part.triangles[standing], part.colour))
    layers.sort(key=lambda layer: (round(layer.height, 4), -layer.area))
    return layers, solids


def _layer(part: Part, keep: np.ndarray) -> Layer | None:
    triangles = part.triangles[keep]
    flat = triangles[:, :, :2]
    area = float(np.abs(triangle_areas(flat)).sum())
    if area < MIN_LAYER_AREA_M2:
        return None
    uv_map = None if part.texture is None else fit_uv_map(flat, part.uv[keep])
    return Layer(flat, part.colour, float(np.median(triangles[:, :, 2])), area,
                 None if uv_map is None else part.texture, uv_map, part.texture_name or "")


def fit_uv_map(points: np.ndarray, uv: np.ndarray) -> np.ndarray | None:
    """The affine map (x, y) -> (u, v) that SketchUp's planar texture projection is, fitted over all
    corners (None when the coordinates are not one affine projection: such a texture is drawn flat)."""
    xy1 = np.column_stack([points.reshape(-1, 2), np.ones(points.size // 2)])
    target = uv.reshape(-1, 2)
    solution, *_ = np.linalg.lstsq(xy1, target, rcond=None)
    error = np.abs(xy1 @ solution - target).max()
    return solution.T if error < 0.05 else None
