"""Synthetic but learnable driving data: a red stripe on a grey road; where it is sets w."""
from __future__ import annotations

import numpy as np

from pilotlab.data.frames import FrameSet


def stripe_images(n: int, height: int = 66, width: int = 200, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(uint8 [n, height, width, 3] RGB, float32 [n, 2] labels): w = how far right the stripe is."""
    rng = np.random.default_rng(seed)
    position = rng.uniform(0.1, 0.9, n)
    images = np.empty((n, height, width, 3), np.uint8)
    columns = np.arange(width)
    for i, x in enumerate(position):
        grey = rng.integers(70, 140)
        image = np.full((height, width, 3), grey, np.int16) + rng.integers(-12, 12, (height, width, 1))
        stripe = np.abs(columns - x * width) < width * 0.04
        image[:, stripe] = (200, 30, 30)
        images[i] = np.clip(image, 0, 255)
    w = (0.5 - position) * 3.0                    # stripe on the right: turn right (negative w)
    labels = np.stack([4.0 - 2.0 * np.abs(w), w], 1).astype(np.float32)
    return images, labels


def stripe_frameset(recordings: int, per_recording: int, seed: int = 0) -> FrameSet:
    images, labels = stripe_images(recordings * per_recording, seed=seed)
    return FrameSet(images, labels, np.repeat(np.arange(recordings), per_recording).astype(np.int32))
