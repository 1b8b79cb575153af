"""The forward camera: its optics, where it sits on the car, and the palette of the world it sees.

The full frame is 640×480 with a 70° horizontal field of view and the horizon across its middle,
like the JdeRobot F1 car's camera (DeepLearningStudio crops the lower half and resizes it to 200×66).
`CameraSpec.window` renders only part of that frame, at any size: `CameraSpec.crop()` renders the
network's input (the lower half, resized to 200×66) directly, without rendering the full frame.

Pixel conventions are OpenCV's: u right, v down, pixel centres at integers; the camera frame is
x right, y down, z forward.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pilotlab.errors import PilotlabError

# The world's colours (RGB). Renderers shade nothing, so these are exactly the colours in the image.
SKY = (170, 200, 235)
GROUND = (86, 125, 70)
ROAD = (90, 90, 90)
LINE = (205, 30, 30)
WALL = (225, 225, 215)
LINE_WIDTH_M = 0.25


@dataclass(frozen=True)
class CameraSpec:
    width: int = 640
    height: int = 480
    hfov_deg: float = 70.0                 # horizontal field of view of the full frame
    aspect: float = 4 / 3                  # full frame width / height
    # (left, top, right, bottom) of the full frame, as fractions, rendered into width × height.
    window: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0)
    forward_m: float = 0.9                 # mount ahead of the car's centre (between the axles)
    height_m: float = 0.9                  # lens height above the ground
    pitch_deg: float = 0.0                 # + looks down
    near_m: float = 0.1
    far_m: float = 300.0
    lateral_m: float = 0.0                 # mount left of the car's centre line
    # A level camera turns with the car's yaw only (not its pitch and roll on the suspension), as a
    # camera on a planar-move car in Gazebo does: the BM world renderer relies on it (pilotlab.worlds).
    level: bool = False
    version: int = 2

    def __post_init__(self):
        left, top, right, bottom = self.window
        if not (self.width > 0 and self.height > 0):
            raise PilotlabError(f"camera size must be positive, got {self.width}×{self.height}")
        if not (0 <= left < right <= 1 and 0 <= top < bottom <= 1):
            raise PilotlabError(f"camera window {self.window} must be (left, top, right, bottom) fractions "
                                "of the full frame with left < right and top < bottom")

    @classmethod
    def crop(cls, width: int = 200, height: int = 66, top: float = 0.5, **options) -> CameraSpec:
        """The network's input rendered directly: rows from `top` (fraction) to the bottom of the
        full frame, resized to width × height (DeepLearningStudio: lower half, 200×66)."""
        return cls(width=width, height=height, window=(0.0, top, 1.0, 1.0), **options)

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    def in_bm_world(self) -> bool:
        """Whether this is BM's F1 camera (bm_camera): optics and mount, at any window."""
        full = bm_camera()
        return all(getattr(self, name) == getattr(full, name) for name in
                   ("hfov_deg", "aspect", "forward_m", "height_m", "lateral_m", "pitch_deg", "far_m", "level"))

    def plane_bounds(self) -> tuple[float, float, float, float]:
        """(left, top, right, bottom) of the rendered window on the image plane at depth 1
        (x right, y down)."""
        half_w = math.tan(math.radians(self.hfov_deg) / 2)
        half_h = half_w / self.aspect
        left, top, right, bottom = self.window
        return (-half_w + 2 * half_w * left, -half_h + 2 * half_h * top,
                -half_w + 2 * half_w * right, -half_h + 2 * half_h * bottom)

    def intrinsics(self) -> np.ndarray:
        """K mapping camera coordinates to pixels (OpenCV: centre of the top-left pixel at 0, 0).

        It describes pybullet's image exactly: TinyRenderer samples pixel i at window coordinate i
        (not i + 0.5) and flips rows, which moves its image half a pixel right and half a pixel up
        from the textbook OpenGL frustum (measured: the red-line IoU of the two renderers at 200×66
        goes from 0.84 to 0.99 with this offset)."""
        left, top, right, bottom = self.plane_bounds()
        fx, fy = self.width / (right - left), self.height / (bottom - top)
        return np.array([[fx, 0.0, -left * fx], [0.0, fy, -top * fy - 1.0], [0.0, 0.0, 1.0]])

    def pinhole_intrinsics(self) -> np.ndarray:
        """K of an ideal pinhole camera (as Gazebo's): pixel i's centre looks through window coordinate
        i + 0.5. The BM world renderer uses it (pilotlab.worlds.render); `intrinsics` is TinyRenderer's."""
        left, top, right, bottom = self.plane_bounds()
        fx, fy = self.width / (right - left), self.height / (bottom - top)
        return np.array([[fx, 0.0, -left * fx - 0.5], [0.0, fy, -top * fy - 0.5], [0.0, 0.0, 1.0]])

    def gl_projection(self, pixel_shift: tuple[float, float] = (0.0, 0.0)) -> list[float]:
        """The same optics as an OpenGL off-axis frustum (column-major), for pybullet; `pixel_shift`
        (du, dv) moves the window by that many pixels (right, down)."""
        left, top, right, bottom = self.plane_bounds()
        du, dv = pixel_shift[0] * (right - left) / self.width, pixel_shift[1] * (bottom - top) / self.height
        left, right, top, bottom = left + du, right + du, top + dv, bottom + dv
        n, f = self.near_m, self.far_m
        l, r, b, t = left * n, right * n, -bottom * n, -top * n  # OpenGL's y points up
        matrix = np.array([[2 * n / (r - l), 0, (r + l) / (r - l), 0],
                           [0, 2 * n / (t - b), (t + b) / (t - b), 0],
                           [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
                           [0, 0, -1, 0]])
        return matrix.T.reshape(-1).tolist()


def bm_camera(**options) -> CameraSpec:
    """BehaviorMetrics' F1 camera (models/f1_renault/model.sdf, sensor cam_f1_left): 640×480, horizontal
    FOV 1.57 rad, clip 0.1-15 m, at (0.45, 0.04, 0.10) m in the car's frame with no pitch; the car's
    origin is spawned 4 mm above the road, so the lens is 0.104 m up. `options` override (a window...)."""
    settings = dict(hfov_deg=math.degrees(1.57), forward_m=0.45, lateral_m=0.04, height_m=0.104,
                    near_m=0.1, far_m=15.0, level=True)
    return CameraSpec(**{**settings, **options})


def camera_pose(spec: CameraSpec, position, quaternion, axle_height: float) -> tuple[np.ndarray, np.ndarray]:
    """(eye in the world, R world->camera) for a camera on a car whose centre is at `position`
    (at axle height) with orientation `quaternion` (x, y, z, w; the car looks along its +x)."""
    car = level_matrix(quaternion) if spec.level else quaternion_matrix(quaternion)  # columns: forward, left, up
    eye = np.asarray(position) + car @ np.array([spec.forward_m, spec.lateral_m, spec.height_m - axle_height])
    pitch = math.radians(spec.pitch_deg)
    forward = car @ np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    down = car @ np.array([-math.sin(pitch), 0.0, -math.cos(pitch)])
    # np.cross's arithmetic, without its per-call overhead (the camera moves every step)
    right = np.array([down[1] * forward[2] - down[2] * forward[1], down[2] * forward[0] - down[0] * forward[2],
                      down[0] * forward[1] - down[1] * forward[0]])
    return eye, np.stack([right, down, forward])


def level_matrix(q) -> np.ndarray:
    """The rotation of quaternion q's yaw alone (the car's heading, level)."""
    x, y, z, w = q
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def quaternion_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@dataclass(frozen=True)
class PixelGrid:
    """Which points of the full frame an image samples: its pixel (j, k), of `width` × `height`, looks
    at the full frame's pixel coordinates (scale·j + u0, scale·k + v0). A renderer given a grid draws
    only those samples: a crop of the full frame (scale 1), or one sample per scale×scale block of it."""
    width: int
    height: int
    scale: float = 1.0
    u0: float = 0.0
    v0: float = 0.0

    @classmethod
    def full(cls, spec: CameraSpec) -> PixelGrid:
        return cls(spec.width, spec.height)

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    def intrinsics(self, spec: CameraSpec, pinhole: bool = False) -> np.ndarray:
        """K of these samples: the full frame's K (TinyRenderer's, or with `pinhole` the ideal one)
        followed by full-frame pixels -> grid pixels."""
        to_grid = np.array([[1 / self.scale, 0.0, -self.u0 / self.scale],
                            [0.0, 1 / self.scale, -self.v0 / self.scale], [0.0, 0.0, 1.0]])
        return to_grid @ (spec.pinhole_intrinsics() if pinhole else spec.intrinsics())


def sky_polygon(spec: CameraSpec, rotation: np.ndarray, intrinsics_inverse: np.ndarray | None = None,
                size: tuple[int, int] | None = None) -> np.ndarray:
    """The part of the image whose rays point at or above the horizon, as a polygon in pixels
    (empty when the camera sees only ground). `intrinsics_inverse` and `size` describe the image when it
    is not the spec's own (a PixelGrid's); passing the inverse also saves inverting K every frame."""
    inverse = np.linalg.inv(spec.intrinsics()) if intrinsics_inverse is None else intrinsics_inverse
    width, height = size or spec.size
    # The world z of the ray through pixel (u, v) is linear in (u, v, 1).
    a, b, c = (rotation.T @ inverse)[2]
    corners = [(-0.5, -0.5), (width - 0.5, -0.5), (width - 0.5, height - 0.5), (-0.5, height - 0.5)]
    kept = []
    for (u0, v0), (u1, v1) in zip(corners, corners[1:] + corners[:1]):
        h0, h1 = a * u0 + b * v0 + c, a * u1 + b * v1 + c
        if h0 >= 0:
            kept.append((u0, v0))
        if (h0 >= 0) != (h1 >= 0):
            t = h0 / (h0 - h1)
            kept.append((u0 + t * (u1 - u0), v0 + t * (v1 - v0)))
    return np.array(kept, dtype=np.float64).reshape(-1, 2)
