"""The "explicit brain": follows the red (or white) line in the camera image with OpenCV only.

The classic BehaviorMetrics baseline: threshold red in HSV, find the line's centre in bands of rows
below the horizon, steer with a PD controller on the nearest band that sees the line, and slow down
when the bands further ahead say a curve is coming. When the line is lost it keeps turning, slowly,
the way it last saw it. It reads a full camera frame (horizon across the middle); rows are fractions
of the height, so any frame size works, and a crop of the frame too (`act(image, shown=(top, bottom))`:
in a closed loop it is given only the rows below its highest band, at half resolution, which the
simulator renders at a sixth of the full frame's cost: pilotlab.online.brains.ExplicitReference).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pilotlab.errors import PilotlabError


@dataclass(frozen=True)
class ExplicitBrainConfig:
    # Bands of rows (fractions of the image height; the horizon is at 0.5) and how far ahead they see.
    near_rows: tuple[float, float] = (0.75, 0.85)   # 3-4 m: steer on this
    low_rows: tuple[float, float] = (0.88, 0.98)    # 2-3 m: steer on this when the near band is empty
    mid_rows: tuple[float, float] = (0.60, 0.66)    # 6-9 m  } is a curve coming? slow down
    far_rows: tuple[float, float] = (0.53, 0.56)    # 15-30 m }
    kp: float = 2.0                  # rad/s per unit of normalised offset (1 = image edge)
    kd: float = 2.0                  # rad/s per unit of change of the offset between two frames
    max_turn: float = 2.5            # rad/s
    max_speed: float = 12.0
    min_speed: float = 6.0
    slow_down: float = 10.0          # m/s of speed lost per unit of offset ahead (a lost far line counts 1)
    lost_speed: float = 2.0
    lost_turn: float = 1.0
    line: str = "red"                # the line's colour: red, or white (BM's *_white_line worlds)
    version: int = 2

    def __post_init__(self):
        if self.line not in LINE_COLOURS:
            raise PilotlabError(f"explicit brain: line {self.line!r} is not a colour it follows; use one of: "
                                f"{', '.join(LINE_COLOURS)}")


# BM's F1 camera (pilotlab.sim.camera.bm_camera) sits 0.104 m up with a 90° field of view: the ground a
# few metres ahead is a few rows below the horizon, so its bands are there (rows measured as fractions
# of the height; row 0.5 + 0.104·320/(d·480) sees the ground d metres ahead).
BM_CAMERA_ROWS = {"near_rows": (0.535, 0.56), "low_rows": (0.56, 0.62), "mid_rows": (0.515, 0.525),
                  "far_rows": (0.508, 0.513)}


def bm_world_options(line_colour: tuple[int, int, int] | None) -> dict:
    """The explicit brain's options in a BM world: the bands of BM's camera, the world's line colour."""
    white = line_colour is not None and min(line_colour) > 200
    return {**BM_CAMERA_ROWS, "line": "white" if white else "red"}


def red_mask(image: np.ndarray) -> np.ndarray:
    """Pixels of the red line (the image is RGB)."""
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    low = cv2.inRange(hsv, (0, 120, 70), (10, 255, 255))
    high = cv2.inRange(hsv, (170, 120, 70), (180, 255, 255))
    return cv2.bitwise_or(low, high)


def white_mask(image: np.ndarray) -> np.ndarray:
    """Pixels of a white line: bright and colourless (light grey road edges and walls stay out)."""
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    return cv2.inRange(hsv, (0, 0, 235), (180, 30, 255))


LINE_COLOURS = {"red": red_mask, "white": white_mask}


def line_offset(mask: np.ndarray, rows: tuple[float, float], shown: tuple[float, float] = (0.0, 1.0)) -> float | None:
    """Mean column of the red pixels in a band of rows, as -1 (left edge) .. 1 (right edge). `rows` are
    fractions of the camera frame's height; `shown`, the rows of the frame the mask covers."""
    height, width = mask.shape
    top, bottom = ((r - shown[0]) / (shown[1] - shown[0]) for r in rows)
    band = mask[max(int(top * height), 0):max(int(bottom * height), int(top * height) + 1)]
    columns = np.nonzero(band)[1]
    if len(columns) == 0:
        return None
    return float(columns.mean() / (width - 1) * 2 - 1)


class ExplicitBrain:
    def __init__(self, config: ExplicitBrainConfig = ExplicitBrainConfig()):
        self.config = config
        self.reset()

    def reset(self) -> None:
        self._last_offset, self._last_band = 0.0, None

    @property
    def top_row(self) -> float:
        """The highest row any band looks at (a fraction of the frame's height)."""
        config = self.config
        return min(rows[0] for rows in (config.near_rows, config.low_rows, config.mid_rows, config.far_rows))

    def act(self, image: np.ndarray, shown: tuple[float, float] = (0.0, 1.0)) -> tuple[float, float]:
        """The command for a camera frame, or for rows `shown` of it (fractions of its height: a crop)."""
        config = self.config
        mask = LINE_COLOURS[config.line](image)
        band, offset = "near", line_offset(mask, config.near_rows, shown)
        if offset is None:
            band, offset = "low", line_offset(mask, config.low_rows, shown)
        if offset is None:  # line lost: turn towards where it was last seen
            self._last_band = None
            return config.lost_speed, -float(np.sign(self._last_offset)) * config.lost_turn
        change = offset - self._last_offset if band == self._last_band else 0.0
        w = float(np.clip(-config.kp * offset - config.kd * change, -config.max_turn, config.max_turn))
        self._last_offset, self._last_band = offset, band
        ahead = [line_offset(mask, rows, shown) for rows in (config.mid_rows, config.far_rows)]
        curve = max([abs(offset)] + [1.0 if a is None else abs(a) for a in ahead])
        v = float(np.clip(config.max_speed - config.slow_down * curve, config.min_speed, config.max_speed))
        return v, w
