"""FrameSet: preprocessed frames with labels, the form every consumer of a dataset uses.

A FrameSet is saved as a folder: `frames.npy` uint8 [N, 66, 200, 3] RGB (already cropped and
resized), `labels.npy` float32 [N, 2] physical (v m/s, w rad/s), `recording.npy` int32 [N]
(which recording each frame came from, for validation splits and frame stacking), and `meta.json`.
Loading memory-maps the arrays, so epochs and reruns never decode bags again.
"""
from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import torch


@dataclass(frozen=True)
class LabelRanges:
    """Normalisation of labels: (x - lo) / (hi - lo), stored in checkpoints as {"v": [lo, hi], ...}."""
    v: tuple[float, float]
    w: tuple[float, float]

    def as_dict(self) -> dict[str, list[float]]:
        return {"v": list(self.v), "w": list(self.w)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LabelRanges:
        return cls(tuple(d["v"]), tuple(d["w"]))

    @classmethod
    def covering(cls, labels: np.ndarray) -> LabelRanges:
        """Ranges that cover `labels` [N, 2]: v from its min to its max, w symmetric about 0 (so a
        flipped image's label stays in range). A constant label gets a span of 1 around it."""
        labels = np.asarray(labels, np.float64).reshape(-1, 2)
        v_lo, v_hi = float(labels[:, 0].min()), float(labels[:, 0].max())
        if v_hi - v_lo < 1e-6:
            v_lo, v_hi = v_lo - 0.5, v_hi + 0.5
        w_max = float(np.abs(labels[:, 1]).max()) or 0.5
        return cls((v_lo, v_hi), (-w_max, w_max))

    def normalise(self, labels: np.ndarray) -> np.ndarray:
        lo, span = self._lo_span()
        return ((labels - lo) / span).astype(np.float32)

    def denormalise(self, normalised: np.ndarray) -> np.ndarray:
        lo, span = self._lo_span()
        return (normalised * span + lo).astype(np.float32)

    def _lo_span(self) -> tuple[np.ndarray, np.ndarray]:
        lo = np.array([self.v[0], self.w[0]], np.float32)
        return lo, np.array([self.v[1], self.w[1]], np.float32) - lo


@dataclass
class FrameSet:
    frames: np.ndarray                 # uint8 [N, H, W, 3] RGB
    labels: np.ndarray                 # float32 [N, 2] physical v, w
    recording: np.ndarray              # int32 [N]
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.labels)

    def check_finite(self, what: str) -> None:
        """A PilotlabError when a label is NaN or infinite (readers refuse such labels: this guards
        FrameSets built elsewhere, whose NaN would train to a NaN loss and an MSE of NaN)."""
        bad = np.flatnonzero(~np.isfinite(np.asarray(self.labels)).all(axis=1))
        if len(bad):
            from pilotlab.errors import PilotlabError
            i = int(bad[0])
            raise PilotlabError(f"{what}: {len(bad)} of {len(self)} labels are not finite numbers (first: frame {i} "
                                f"of recording {int(self.recording[i])}, v, w = {tuple(map(float, self.labels[i]))}); "
                                "fix or remove those frames in the source recording")

    def save(self, folder: Path) -> None:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        np.save(folder / "frames.npy", self.frames)
        np.save(folder / "labels.npy", self.labels.astype(np.float32))
        np.save(folder / "recording.npy", self.recording.astype(np.int32))
        (folder / "meta.json").write_text(json.dumps(self.meta, indent=1))

    @classmethod
    def load(cls, folder: Path, mmap: bool = True) -> FrameSet:
        folder, mode = Path(folder), "r" if mmap else None
        return cls(np.load(folder / "frames.npy", mmap_mode=mode),
                   np.load(folder / "labels.npy", mmap_mode=mode),
                   np.load(folder / "recording.npy", mmap_mode=mode),
                   json.loads((folder / "meta.json").read_text()))

    @classmethod
    def concat(cls, sets: list[FrameSet]) -> FrameSet:
        """One set from several; recordings are renumbered so they stay distinct."""
        offsets = np.cumsum([0] + [int(s.recording.max()) + 1 if len(s) else 0 for s in sets[:-1]])
        return cls(np.concatenate([s.frames for s in sets]),
                   np.concatenate([s.labels for s in sets]),
                   np.concatenate([s.recording + o for s, o in zip(sets, offsets)]).astype(np.int32),
                   {"parts": [s.meta for s in sets]})

    def subset(self, index: np.ndarray) -> FrameSet:
        return FrameSet(self.frames[index], self.labels[index], self.recording[index], self.meta)

    def stack_index(self, index: np.ndarray, frames: int) -> np.ndarray:
        """[len(index), frames] indices of each frame and its predecessors in the same recording
        (oldest first); the first frames of a recording repeat their earliest frame."""
        offsets = np.arange(frames - 1, -1, -1)
        candidates = np.maximum(index[:, None] - offsets[None, :], 0)
        same = self.recording[candidates] == self.recording[index][:, None]
        # Where a predecessor belongs to another recording, fall back to the frame itself's earliest
        # frame of the same recording: walk right until the recording matches.
        for column in range(frames - 2, -1, -1):
            candidates[:, column] = np.where(same[:, column], candidates[:, column], candidates[:, column + 1])
            same[:, column] = True
        return candidates

    def inputs(self, index: np.ndarray, frames: int = 1) -> torch.Tensor:
        """float32 [len(index), 3 × frames, H, W] in [0, 1] (the network's input), C-contiguous (NCHW):
        the permuted view of the NHWC frames would carry channels-last strides into the network, where
        torch's BatchNorm over 3 channels is 10× slower (30 against 3 ms on a batch of 64, torch 2.13)."""
        import torch  # only here: planning imports this module (via the strategy registry) and needs no torch
        index = np.asarray(index)
        if frames == 1:
            batch = np.asarray(self.frames[index])
            nchw = torch.from_numpy(batch).permute(0, 3, 1, 2)
            return nchw.to(torch.float32, memory_format=torch.contiguous_format).div_(255.0)
        stacked = np.asarray(self.frames[self.stack_index(index, frames)])     # [B, F, H, W, 3]
        tensor = torch.from_numpy(stacked).permute(0, 1, 4, 2, 3).float().div_(255.0)
        return tensor.reshape(len(index), 3 * frames, *tensor.shape[-2:])

    def batches(self, batch_size: int, *, frames: int = 1, shuffle: bool = False,
                seed: int = 0) -> Iterator[tuple[torch.Tensor, np.ndarray]]:
        """(inputs, index) batches over the whole set."""
        order = np.random.default_rng(seed).permutation(len(self)) if shuffle else np.arange(len(self))
        for start in range(0, len(order), batch_size):
            index = order[start:start + batch_size]
            yield self.inputs(index, frames), index
