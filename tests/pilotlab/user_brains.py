"""Brains as a user writes them, for the tests: files written into a test's folder."""
from __future__ import annotations

from pathlib import Path

# A proportional controller on the red line: where the line crosses a band of rows 3-4 m ahead.
RED_LINE = '''
import numpy as np


class RedLine:
    """Steer towards the red line at a steady speed."""

    def __init__(self, speed=7.0, gain=3.0):
        self.speed, self.gain = speed, gain
        self.resets = 0
        self.reset()

    def reset(self):
        self.w = 0.0
        self.resets += 1

    def act(self, image):
        height, width = image.shape[:2]
        rows = image[int(0.75 * height):int(0.85 * height)].astype(int)
        red = (rows[..., 0] > 150) & (rows[..., 1] < 80) & (rows[..., 2] < 80)
        columns = np.nonzero(red)[1]
        if len(columns) == 0:          # line lost: slowly, the way it last turned
            return self.speed / 3, self.w
        offset = columns.mean() / (width - 1) * 2 - 1      # -1 left edge .. 1 right edge
        self.w = -self.gain * offset
        return self.speed, self.w
'''


def write_red_line(folder: Path, name: str = "brains/mine.py") -> Path:
    """The red-line brain as `folder/name`; its spec is f"{name}:RedLine"."""
    path = Path(folder) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(RED_LINE)
    return path
