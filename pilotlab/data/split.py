"""Validation splits that never put frames of one run on both sides at random.

- by "recording": whole recordings are held out, about `fraction` of the frames;
- by "block": the last `fraction` of every recording is held out (one contiguous stretch each),
  for when every recording is needed in training (for example one run per circuit);
- "auto" (default): by recording when there are at least 3 recordings (so at least two stay in
  training), else by block.
A single recording cannot be split by recording; it is split by block, and the split says so.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pilotlab.errors import PilotlabError

SPLITS = ("auto", "recording", "block")
AUTO_MIN_RECORDINGS = 3


@dataclass(frozen=True)
class Split:
    train: np.ndarray          # frame indices
    val: np.ndarray
    by: str                    # how it was split in the end
    val_recordings: list[int]  # recordings held out whole (by recording)


def split_validation(recording: np.ndarray, fraction: float, by: str = "auto", seed: int = 0) -> Split:
    recording = np.asarray(recording)
    if by not in SPLITS:
        raise PilotlabError(f"validation split {by!r} is not one of {', '.join(SPLITS)}")
    if not 0.0 <= fraction < 1.0:
        raise PilotlabError(f"val_fraction = {fraction} must be at least 0 and below 1 (a fraction of the frames)")
    everything = np.arange(len(recording))
    if fraction == 0.0:
        return Split(everything, everything[:0], "none", [])
    runs = np.unique(recording)
    if by == "auto":
        by = "recording" if len(runs) >= AUTO_MIN_RECORDINGS else "block"
    if by == "recording" and len(runs) > 1:
        return _by_recording(recording, runs, fraction, seed)
    return _by_block(recording, runs, fraction)


def _by_recording(recording: np.ndarray, runs: np.ndarray, fraction: float, seed: int) -> Split:
    """Recordings in a seeded random order are held out until they hold `fraction` of the frames
    (at least one; never all)."""
    order = np.random.default_rng(seed).permutation(runs)
    sizes = np.array([np.sum(recording == r) for r in order])
    target = fraction * len(recording)
    count = max(1, min(len(runs) - 1, int(np.argmin(np.abs(np.cumsum(sizes) - target))) + 1))
    held = sorted(int(r) for r in order[:count])
    mask = np.isin(recording, held)
    return Split(np.flatnonzero(~mask), np.flatnonzero(mask), "recording", held)


def _by_block(recording: np.ndarray, runs: np.ndarray, fraction: float) -> Split:
    val = np.zeros(len(recording), bool)
    for run in runs:
        frames = np.flatnonzero(recording == run)
        held = int(round(fraction * len(frames)))
        if held:
            val[frames[len(frames) - held:]] = True
    return Split(np.flatnonzero(~val), np.flatnonzero(val), "block", [])
