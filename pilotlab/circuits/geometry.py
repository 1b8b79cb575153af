"""Centreline geometry: turning a recorded list of x, y points into a smooth closed red line.

The published centrelines are recorded laps rasterised on a ~0.13 m grid (0.33 m for montreal), so
their raw polyline is a staircase: its length over-counts by up to 8 % and its curvature is noise.
We close the loop, resample uniformly, and smooth with a Gaussian along the arc (sigma 1.5 m moves the
line by about 0.1 m on average); the smoothed line *is* the red line the simulator draws and every
metric measures against.
"""
from __future__ import annotations

import numpy as np

from pilotlab.errors import PilotlabError

SPACING_M = 0.25        # distance between resampled centreline points
SMOOTHING_M = 1.5       # Gaussian sigma along the arc
CLOSE_TOLERANCE_M = 2.0  # a recorded lap that passes this close to its start again is cut there ...
CLOSE_ALIGNMENT = 0.7     # ... driving within ~45° of the start's direction (cos), not across it
HEADING_REACH_M = 3.0     # the direction of travel at a point: over this many metres either side
MAX_LENGTH_M = 100_000.0  # longer than any race track: a longer lap is a unit error (and 4e5 points)
MAX_OPEN_GAP = 0.1        # a lap that stops short by more than this share of its length is no lap
MIN_OPEN_GAP_M = 10.0     # ... and by more than this
POLYGON_CLOSING = 1.5     # ... unless that gap is no longer than this × its longest segment (a polygon's corners)
ROUND_ENOUGH = 0.2        # 4πA/L² of a loop that encloses an area for its size (a circle: 1; a line: 0)


def drop_repeats(points: np.ndarray, min_step: float = 1e-6) -> np.ndarray:
    """The points without consecutive duplicates (a car standing still records the same point)."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return points[np.concatenate([[True], steps > min_step])]


def polyline_length(points: np.ndarray, closed: bool = False) -> float:
    path = np.vstack([points, points[:1]]) if closed else points
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def close_loop(points: np.ndarray, tolerance: float = CLOSE_TOLERANCE_M) -> np.ndarray:
    """One lap of `points`, without a repeated end: a lap that overruns its start is cut where it
    passes closest to the start again; a lap that stops short is closed by a straight segment."""
    points = drop_repeats(np.asarray(points, dtype=np.float64))
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    tail = np.flatnonzero(arc > 0.5 * arc[-1])
    if len(tail) == 0:
        return points
    distance = np.linalg.norm(points[tail] - points[0], axis=1)
    # The first pass near the start in the far half of the lap, driven the way the lap starts, is where
    # the lap closes; a pass across the start (a figure eight started at its crossing) is not.
    near = np.flatnonzero(distance < tolerance)
    start = _heading(points, arc, 0)
    for group in np.split(near, np.flatnonzero(np.diff(near) > 1) + 1) if len(near) else ():
        closest = tail[group[np.argmin(distance[group])]]
        if np.dot(_heading(points, arc, closest), start) > CLOSE_ALIGNMENT:
            return points[:closest]
    return points


def _heading(points: np.ndarray, arc: np.ndarray, index: int, reach: float = HEADING_REACH_M) -> np.ndarray:
    """Unit direction of travel at `index`: from `reach` metres before it to `reach` metres after it."""
    before = points[np.searchsorted(arc, arc[index] - reach)]
    after = points[min(np.searchsorted(arc, arc[index] + reach), len(points) - 1)]
    step = after - before
    return step / (np.linalg.norm(step) or 1.0)


def resample_closed(points: np.ndarray, spacing: float) -> np.ndarray:
    """Points evenly spaced along the closed polyline (the closing segment included)."""
    path = np.vstack([points, points[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    count = max(int(round(arc[-1] / spacing)), 8)
    at = np.arange(count) * (arc[-1] / count)
    return np.stack([np.interp(at, arc, path[:, 0]), np.interp(at, arc, path[:, 1])], axis=1)


def smooth_closed(values: np.ndarray, sigma_samples: float) -> np.ndarray:
    """Circular Gaussian smoothing along axis 0."""
    if sigma_samples <= 0:
        return values
    radius = int(np.ceil(3 * sigma_samples))
    kernel = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma_samples) ** 2)
    kernel /= kernel.sum()
    count = len(values)
    if radius >= count:
        raise PilotlabError(f"a circuit of {count} points is too short to smooth over {radius} points; "
                            "give a longer centreline or less smoothing")
    padded = np.concatenate([values[-radius:], values, values[:radius]])
    columns = padded.reshape(len(padded), -1).T
    smoothed = np.stack([np.convolve(c, kernel, mode="valid") for c in columns], axis=1)
    return smoothed.reshape(values.shape)


def signed_area(points: np.ndarray) -> float:
    """Shoelace area: negative for a clockwise loop (x east, y north)."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def centreline(points: np.ndarray, spacing: float = SPACING_M, smoothing: float = SMOOTHING_M) -> np.ndarray:
    """The smooth closed centreline (evenly spaced, no repeated end) of a recorded lap."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3:
        raise PilotlabError(f"a centreline needs at least 3 x, y points, got an array of shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise PilotlabError(f"point {int(np.flatnonzero(~np.isfinite(points).all(axis=1))[0]) + 1} of the "
                            "centreline is not a finite number")
    lap = close_loop(points)
    _check_lap(lap)
    if polyline_length(lap, closed=True) < 8 * spacing:
        raise PilotlabError(f"the centreline is only {polyline_length(lap, closed=True):.2f} m long; "
                            "a circuit needs a closed lap of at least a few metres")
    even = resample_closed(lap, spacing)
    smooth = smooth_closed(even, smoothing / spacing)
    return resample_closed(smooth, spacing)


def _check_lap(lap: np.ndarray) -> None:
    length = polyline_length(lap, closed=True)
    if not length <= MAX_LENGTH_M:
        raise PilotlabError(f"the centreline is {length:.3g} m long, more than {MAX_LENGTH_M:g} m; "
                            "are the coordinates in metres?")
    gap = float(np.linalg.norm(lap[-1] - lap[0]))
    # a coarse polygon (a square's four corners) closes with a segment like its others; a recording that
    # stops short leaves a gap far longer than its steps
    longest_step = float(np.linalg.norm(np.diff(lap, axis=0), axis=1).max())
    if gap > MIN_OPEN_GAP_M and gap > MAX_OPEN_GAP * length and gap > POLYGON_CLOSING * longest_step:
        raise PilotlabError(f"the centreline is not a lap: it ends {gap:.1f} m from its start "
                            f"({100 * gap / length:.0f} % of its length); give the points of one whole lap")


def check_loop(points: np.ndarray, road_width: float) -> None:
    """A closed centreline a car can drive: it encloses an area and never crosses itself."""
    crossing = self_intersection(points[::4] if len(points) > 64 else points)
    if crossing is not None:
        raise PilotlabError(f"the centreline crosses itself near x={crossing[0]:.1f}, y={crossing[1]:.1f} m; "
                            "a circuit is one loop without crossings")
    length, area = polyline_length(points, closed=True), abs(signed_area(points))
    if area >= 0.25 * length * road_width:
        return
    if 4 * np.pi * area / length ** 2 > ROUND_ENOUGH:
        span = float(np.ptp(points, axis=0).max())
        raise PilotlabError(f"the centreline is too small for its {road_width:g} m road: the lap spans {span:.1f} m "
                            "once smoothed, so the road would cover its inside; give a larger lap (are the "
                            "coordinates in metres?)")
    raise PilotlabError("the centreline encloses almost no area (its points lie on one line, or the "
                        "lap runs back along itself); give the points of a closed lap")


def self_intersection(points: np.ndarray) -> np.ndarray | None:
    """A point where two non-adjacent segments of the closed polyline cross, or None."""
    start, end = points, np.roll(points, -1, axis=0)
    count = len(points)
    for i in range(count):
        j = np.arange(i + 2, count if i else count - 1)   # not the segment itself nor its neighbours
        if len(j) == 0:
            continue
        p, r = start[i], end[i] - start[i]
        q, s = start[j], end[j] - start[j]
        denominator = r[0] * s[:, 1] - r[1] * s[:, 0]
        qp = q - p
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (qp[:, 0] * s[:, 1] - qp[:, 1] * s[:, 0]) / denominator
            u = (qp[:, 0] * r[1] - qp[:, 1] * r[0]) / denominator
        hit = np.flatnonzero((denominator != 0) & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1))
        if len(hit):
            return p + t[hit[0]] * r
    return None
