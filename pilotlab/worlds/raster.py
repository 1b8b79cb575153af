"""Top-down rasters of a BM world's ground, drawn once (then cached): the camera image of flat ground
is a homography of such a raster (pilotlab.worlds.render).

- the colour raster: every layer painted in order, textures sampled through their planar projection
  (pre-filtered to the raster's resolution), lit;
- a signed-distance raster per flat-coloured layer (the line, marks), so that the renderer draws its
  edges within a fraction of a pixel (bilinear sampling, then a threshold) instead of a blurred ramp.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from pilotlab.worlds.scene import Layer

MAX_RASTER_BYTES = 150 * 2**20
FINEST_M = 0.025
SHIFT = 4                   # cv2's sub-pixel bits for polygon corners


@dataclass(frozen=True)
class Grid:
    """Raster pixel (col, row) has its centre at world (x0 + col·res, y1 - row·res)."""
    x0: float
    y1: float
    resolution: float
    width: int
    height: int

    @classmethod
    def around(cls, layers: list[Layer], margin: float = 2.0) -> Grid:
        points = np.concatenate([layer.triangles.reshape(-1, 2) for layer in layers])
        (x0, y0), (x1, y1) = points.min(axis=0) - margin, points.max(axis=0) + margin
        resolution = FINEST_M
        while (x1 - x0) * (y1 - y0) / resolution**2 * (3 + len(layers)) > MAX_RASTER_BYTES:
            resolution *= 2
        return cls(float(x0), float(y1), resolution, int(math.ceil((x1 - x0) / resolution)) + 1,
                   int(math.ceil((y1 - y0) / resolution)) + 1)

    def to_world(self) -> np.ndarray:
        """3×3: raster (col, row, 1) -> world (x, y, 1)."""
        return np.array([[self.resolution, 0, self.x0], [0, -self.resolution, self.y1], [0, 0, 1]])

    def finer(self, factor: int) -> Grid:
        """The same area at `factor` times the resolution (pixel centres on the finer lattice)."""
        resolution = self.resolution / factor
        shift = (self.resolution - resolution) / 2
        return Grid(self.x0 - shift, self.y1 + shift, resolution, self.width * factor, self.height * factor)

    def pixels(self, points: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """World (x, y) -> pixel coordinates of a raster `scale` times finer (cv2's corner convention)."""
        col = (points[..., 0] - self.x0) / self.resolution
        row = (self.y1 - points[..., 1]) / self.resolution
        return np.stack([(col + 0.5) * scale - 0.5, (row + 0.5) * scale - 0.5], axis=-1)


def fill(raster: np.ndarray, grid: Grid, triangles: np.ndarray, value, scale: float = 1.0) -> None:
    """Paint the triangles one by one (cv2.fillPoly of many polygons fills even-odd: overlapping
    triangles, which SketchUp's exports have, would cancel out)."""
    corners = np.round(grid.pixels(triangles, scale) * (1 << SHIFT)).astype(np.int32)
    for triangle in corners:
        cv2.fillConvexPoly(raster, triangle, value, lineType=cv2.LINE_8, shift=SHIFT)


def signed_distance(grid: Grid, layer: Layer) -> np.ndarray:
    """How far each pixel centre lies inside the layer's outline (+) or outside it (-), in pixels, encoded
    as 128 + 64·d (clipped to ±2 pixels). Bilinear sampling of a distance field and the threshold 128
    reconstruct the outline as a smooth line within a small fraction of a pixel, where a coverage ramp
    or the distance transform of a binary mask would show the mask's staircase. The distance is exact:
    computed to the outline's segments (edges used by one triangle only) for pixels within reach."""
    rings = outline_rings(layer.triangles)
    mask = np.zeros((grid.height, grid.width), np.uint8)
    corners = [np.round(grid.pixels(ring) * (1 << SHIFT)).astype(np.int32) for ring in rings]
    cv2.fillPoly(mask, corners, 1, lineType=cv2.LINE_8, shift=SHIFT)   # even-odd: holes stay holes
    out = np.where(mask == 1, 255, 0).astype(np.uint8)
    segments = np.concatenate([np.stack([ring[:-1], ring[1:]], axis=1) for ring in rings])
    pixels, signed = _outline_distances(grid, segments)
    out.ravel()[pixels] = np.clip(np.round(128 + 64 * signed), 0, 255).astype(np.uint8)
    return out


def outline_rings(triangles: np.ndarray) -> list[np.ndarray]:
    """The outline of the union of the triangles, as closed rings (exteriors and holes), merged by
    shapely: SketchUp's meshes have T-junctions and overlapping faces, so the outline is not simply
    the edges that one triangle alone uses. Cracks narrower than 0.1 mm are closed."""
    import shapely  # imported here: only building a world needs it
    union = shapely.union_all(shapely.polygons(np.concatenate([triangles, triangles[:, :1]], axis=1)))
    union = union.buffer(1e-4, join_style="mitre").buffer(-1e-4, join_style="mitre")
    polygons = [shapely.orient_polygons(polygon) for polygon in getattr(union, "geoms", [union])]
    rings = [np.asarray(ring.coords) for polygon in polygons if not polygon.is_empty
             for ring in (polygon.exterior, *polygon.interiors)]
    return [ring for ring in rings if len(ring) >= 4]


def _outline_distances(grid: Grid, segments: np.ndarray, reach: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Flat raster indices within `reach` pixels of the segments and their signed distance (pixels) to
    the nearest one: + on its left (inside, for outline_rings' orientation). cv2's polygon fill is not
    exact to the pixel centre, so the side comes from the geometry, not from a mask. Segments are cut
    into pieces of at most one pixel, each examined in a small box."""
    ends = grid.pixels(segments)                                          # (n, 2, 2) pixel coordinates
    pieces = np.maximum(1, np.ceil(np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)).astype(int))
    t0 = np.concatenate([np.arange(k) / k for k in pieces])
    t1 = np.concatenate([np.arange(1, k + 1) / k for k in pieces])
    owner = np.repeat(np.arange(len(ends)), pieces)
    starts = ends[owner, 0] + t0[:, None] * (ends[owner, 1] - ends[owner, 0])
    stops = ends[owner, 0] + t1[:, None] * (ends[owner, 1] - ends[owner, 0])
    box = int(np.ceil(1 + 2 * reach)) + 1
    corner = np.floor(np.minimum(starts, stops) - reach).astype(int)      # (pieces, 2) col, row
    offset_r, offset_c = np.divmod(np.arange(box * box), box)
    cols, rows = corner[:, :1] + offset_c[None], corner[:, 1:] + offset_r[None]
    along = stops - starts
    length2 = np.maximum(np.sum(along**2, axis=1), 1e-12)[:, None]
    t = np.clip(((cols - starts[:, :1]) * along[:, :1] + (rows - starts[:, 1:]) * along[:, 1:]) / length2, 0, 1)
    distance = np.hypot(cols - starts[:, :1] - t * along[:, :1], rows - starts[:, 1:] - t * along[:, 1:])
    # pixel rows grow downwards (y flipped), so the world's left of a segment has a negative cross product
    cross = along[:, :1] * (rows - starts[:, 1:]) - along[:, 1:] * (cols - starts[:, :1])
    keep = (distance <= reach) & (cols >= 0) & (rows >= 0) & (cols < grid.width) & (rows < grid.height)
    flat, distance = (rows * grid.width + cols)[keep], distance[keep]
    signed = np.where(cross[keep] < 0, distance, -distance)
    order = np.lexsort((distance, flat))                     # by pixel, nearest first
    flat, signed = flat[order], signed[order]
    first = np.flatnonzero(np.r_[True, flat[1:] != flat[:-1]])
    return flat[first], signed[first]


def layer_colours(grid: Grid, layer: Layer, mask: np.ndarray) -> np.ndarray:
    """RGB of the layer at the raster's pixels where `mask` holds: its texture or its flat colour."""
    rows, cols = np.nonzero(mask)
    if layer.texture is None or layer.uv_map is None:
        return np.broadcast_to(np.array(layer.colour, np.uint8), (len(rows), 3))
    x, y = grid.x0 + cols * grid.resolution, grid.y1 - rows * grid.resolution
    u, v = layer.uv_map @ np.stack([x, y, np.ones_like(x)])
    texture = filtered_texture(layer, grid.resolution)
    height, width = texture.shape[:2]
    tex_col = np.floor(np.mod(u, 1.0) * width).astype(np.int64) % width
    tex_row = np.floor(np.mod(1.0 - v, 1.0) * height).astype(np.int64) % height
    tint = np.array(layer.colour, np.float32) / 255
    return np.clip(texture[tex_row, tex_col] * tint, 0, 255).astype(np.uint8)


def filtered_texture(layer: Layer, resolution: float) -> np.ndarray:
    """The texture shrunk so that one texel covers about one raster pixel (no aliasing)."""
    texture = layer.texture
    metres_per_repeat = 1.0 / max(np.linalg.norm(layer.uv_map[0, :2]), 1e-9)
    texels = max(1, int(round(metres_per_repeat / resolution)))
    if texels >= texture.shape[1]:
        return texture
    return cv2.resize(texture, (texels, max(1, round(texels * texture.shape[0] / texture.shape[1]))),
                      interpolation=cv2.INTER_AREA)


def colour_raster(grid: Grid, layers: list[Layer], shades: list[float], background) -> np.ndarray:
    """Every layer painted in order (nearest pixel), textured and lit: the ground's colours."""
    image = np.empty((grid.height, grid.width, 3), np.uint8)
    image[:] = background
    for layer, shade in zip(layers, shades):
        mask = np.zeros((grid.height, grid.width), np.uint8)
        fill(mask, grid, layer.triangles, 1)
        inside = mask.astype(bool)
        image[inside] = np.clip(layer_colours(grid, layer, inside) * shade, 0, 255).astype(np.uint8)
    return image
