"""A circuit: a closed centreline (the red line) with a road around it, driven in one direction.

Coordinates are metres in the world frame (x east, y north, z up). Arc length `s` runs along the
driving direction from the start point; the lateral offset is positive to the left of it. `cw` is
clockwise seen from above (the order the JdeRobot laps were published in), `ccw` the reverse; both
start at the same point.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from pilotlab.circuits.geometry import SMOOTHING_M, SPACING_M, centreline, check_loop, signed_area
from pilotlab.errors import PilotlabError

DIRECTIONS = ("cw", "ccw")


@dataclass(frozen=True)
class Projection:
    """Where a position lies relative to the centreline."""
    s: float            # arc length of the nearest centreline point, in [0, length)
    lateral: float      # signed distance from the red line, + left of the driving direction
    x: float            # the nearest centreline point
    y: float
    heading: float      # driving direction of the centreline there (rad, from +x, counter-clockwise)

    @property
    def distance(self) -> float:
        return abs(self.lateral)


def wrap_angle(angle):
    """Angle(s) wrapped into [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def check_direction(direction: str) -> str:
    if direction not in DIRECTIONS:
        raise PilotlabError(f"unknown direction {direction!r}; use 'cw' (clockwise) or 'ccw'")
    return direction


class Circuit:
    """An evenly spaced closed centreline, its road width and the direction it is driven in."""

    def __init__(self, name: str, points: np.ndarray, *, road_width: float, timeout_s: float,
                 direction: str = "cw", source: str = "", canonical: Circuit | None = None):
        if road_width <= 0:
            raise PilotlabError(f"circuit {name!r}: road width must be positive, got {road_width}")
        self.name, self.road_width, self.timeout_s = name, float(road_width), float(timeout_s)
        self.direction, self.source = check_direction(direction), source
        self.canonical = canonical or self  # the clockwise circuit this one reverses (or itself)
        self._reversed: Circuit | None = None
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        segments = np.roll(self.points, -1, axis=0) - self.points
        self._seg_len = np.linalg.norm(segments, axis=1)
        self._seg_dir = segments / self._seg_len[:, None]
        self.arc = np.concatenate([[0.0], np.cumsum(self._seg_len)[:-1]])
        self.length = float(self._seg_len.sum())
        self.headings = np.arctan2(self._seg_dir[:, 1], self._seg_dir[:, 0])
        turn = wrap_angle(np.roll(self.headings, -1) - np.roll(self.headings, 1))
        self.curvature = turn / (np.roll(self._seg_len, -1) + self._seg_len)  # 1/m, + turning left
        # Per-segment steps to the next point, for the lookups the simulator makes every step.
        self._heading_step = wrap_angle(np.roll(self.headings, -1) - self.headings)
        self._next_curvature = np.roll(self.curvature, -1)
        self._arc_list = self.arc.tolist()

    @classmethod
    def from_points(cls, name: str, raw: np.ndarray, *, road_width: float, timeout_s: float | None = None,
                    source: str = "", spacing: float = SPACING_M, smoothing: float = SMOOTHING_M) -> Circuit:
        """A clockwise circuit from a recorded lap of x, y points (closed, resampled, smoothed)."""
        try:
            points = centreline(raw, spacing, smoothing)
            check_loop(points, road_width)
        except PilotlabError as error:
            raise PilotlabError(f"circuit {name!r} ({source or 'points'}): {error}") from None
        if signed_area(points) > 0:
            points = np.roll(points[::-1], 1, axis=0)
        length = float(np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1).sum())
        timeout = timeout_s if timeout_s is not None else default_timeout(length)
        return cls(name, points, road_width=road_width, timeout_s=timeout, source=source)

    def __repr__(self) -> str:
        return f"Circuit({self.name!r}, {self.direction}, {self.length:.1f} m, road {self.road_width:g} m)"

    # -- directions ---------------------------------------------------------------------------
    def directed(self, direction: str) -> Circuit:
        """This circuit driven in `direction` (same start point)."""
        if check_direction(direction) == self.direction:
            return self
        if self.canonical is not self:
            return self.canonical
        if self._reversed is None:
            reverse = np.roll(self.points[::-1], 1, axis=0)
            self._reversed = Circuit(self.name, reverse, road_width=self.road_width, timeout_s=self.timeout_s,
                                     direction=direction, source=self.source, canonical=self)
        return self._reversed

    # -- lookups along the arc ----------------------------------------------------------------
    def _locate(self, s):
        if isinstance(s, (float, int, np.floating, np.integer)):  # one point: the same numbers, without
            s = float(s) % self.length                                # numpy's per-call overhead
            index = min(max(bisect.bisect_right(self._arc_list, s) - 1, 0), len(self._arc_list) - 1)
            return index, (s - self.arc[index]) / self._seg_len[index]
        s = np.mod(np.asarray(s, dtype=np.float64), self.length)
        index = np.clip(np.searchsorted(self.arc, s, side="right") - 1, 0, len(self.arc) - 1)
        return index, (s - self.arc[index]) / self._seg_len[index]

    def point_at(self, s) -> np.ndarray:
        """x, y of the centreline at arc length(s) `s` (wraps around the lap)."""
        index, t = self._locate(s)
        return self.points[index] + (t * self._seg_len[index])[..., None] * self._seg_dir[index]

    def heading_at(self, s):
        index, t = self._locate(s)
        return wrap_angle(self.headings[index] + t * self._heading_step[index])

    def curvature_at(self, s):
        index, t = self._locate(s)
        return (1 - t) * self.curvature[index] + t * self._next_curvature[index]

    def start_pose(self, s: float = 0.0, lateral: float = 0.0) -> tuple[float, float, float]:
        """x, y, yaw of a car on the centreline at `s`, shifted `lateral` metres to the left."""
        heading = float(self.heading_at(s))
        x, y = self.point_at(s)
        return (float(x - lateral * math.sin(heading)), float(y + lateral * math.cos(heading)), heading)

    def offset_line(self, lateral: float) -> np.ndarray:
        """The closed polyline `lateral` metres to the left of the centreline (road edges, walls)."""
        normals = np.stack([-np.sin(self._point_headings()), np.cos(self._point_headings())], axis=1)
        return self.points + lateral * normals

    def _point_headings(self) -> np.ndarray:
        previous = np.roll(self.headings, 1)
        return wrap_angle(previous + 0.5 * wrap_angle(self.headings - previous))

    # -- projection -----------------------------------------------------------------------------
    def project(self, x: float, y: float, near_s: float | None = None, window: float = 25.0) -> Projection:
        """The nearest centreline point to (x, y). With `near_s`, only segments within `window`
        metres of it are searched (fast, and never jumps to a neighbouring stretch of road)."""
        segments = self._segment_window(near_s, window)
        start, direction = self.points[segments], self._seg_dir[segments]
        point = np.array([x, y])
        offset = point - start
        # np.minimum(np.maximum()) is np.clip without its Python-level overhead (called every step)
        along = np.minimum(np.maximum(np.einsum("ij,ij->i", offset, direction), 0.0), self._seg_len[segments])
        nearest = start + along[:, None] * direction
        squared = np.sum((point - nearest) ** 2, axis=1)
        best = int(np.argmin(squared))
        side = direction[best, 0] * offset[best, 1] - direction[best, 1] * offset[best, 0]
        s = float((self.arc[segments][best] + along[best]) % self.length)
        return Projection(s=s, lateral=math.copysign(math.sqrt(squared[best]), side),
                          x=float(nearest[best, 0]), y=float(nearest[best, 1]), heading=float(self.heading_at(s)))

    def _segment_window(self, near_s: float | None, window: float) -> slice | np.ndarray:
        """The segments to search, in order: a slice where they do not wrap past the start line (views,
        not copies: the env projects the car every step), else their indices."""
        count = len(self.points)
        if near_s is None or 2 * window >= self.length:
            return slice(0, count)
        centre = int(self._locate(near_s)[0])
        half = int(math.ceil(window / (self.length / count)))
        if 0 <= centre - half and centre + half + 1 <= count:
            return slice(centre - half, centre + half + 1)
        return np.arange(centre - half, centre + half + 1) % count

    # -- extent ---------------------------------------------------------------------------------
    def bounds(self, margin: float = 0.0) -> tuple[float, float, float, float]:
        """x_min, y_min, x_max, y_max of the centreline, grown by `margin` metres."""
        low, high = self.points.min(axis=0) - margin, self.points.max(axis=0) + margin
        return float(low[0]), float(low[1]), float(high[0]), float(high[1])


def default_timeout(length_m: float) -> float:
    """BehaviorMetrics' per-lap timeouts are about length / 5.5 m/s; we use 5 m/s for user circuits."""
    return length_m / 5.0
