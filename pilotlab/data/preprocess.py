"""Preprocessing as DeepLearningStudio's PilotNet: crop the lower half, resize to 200×66.

One function, `preprocess`, turns a camera image into the uint8 66×200×3 RGB frame the FrameSet
stores; the bag reader calls it on every decoded message and the simulator's brain calls it on every
live camera image (through `DrivePreprocessor`), so a network sees at drive time exactly what it saw
in training. `to_input` turns such frames into the network's float tensor.

    pre = DrivePreprocessor.from_checkpoint(checkpoint)   # the dict load_checkpoint returns
    # (or DrivePreprocessor.from_settings(meta.preprocess, meta.labels) for an optimized artifact)
    inputs = pre(rgb_image)                                 # [1, 3 × frames, 66, 200] float32
    v, w = pre.commands(model(inputs))                      # physical (m/s, rad/s)
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from typing import Any

import cv2
import numpy as np
import torch

from pilotlab.data.frames import LabelRanges
from pilotlab.errors import PilotlabError
from pilotlab.specs.frames import PreprocessConfig

ENCODINGS = ("rgb8", "bgr8", "mono8")


def resize(image: np.ndarray, width: int, height: int, interpolation: str,
           out: np.ndarray | None = None) -> np.ndarray:
    """Downscale with anti-aliasing.

    - "area": cv2.INTER_AREA, each output pixel the exact average of the input area it covers
      (about 0.7 ms for 640×240 -> 200×66 on one core here);
    - "fast_area": halve by averaging 2×2 blocks (INTER_AREA at exactly half size, OpenCV's fast
      path) while the image is at least twice the target size, then bilinear to the size: within
      about one grey level of "area" and 5-8 times faster here;
    - "linear": cv2.INTER_LINEAR straight to the size (DeepLearningStudio's cv2.resize default);
      cheapest, but it skips most pixels when shrinking 3×, so thin lines alias.
    """
    if interpolation == "area":
        return cv2.resize(image, (width, height), dst=out, interpolation=cv2.INTER_AREA)
    if interpolation == "fast_area":
        while image.shape[1] >= 2 * width and image.shape[0] >= 2 * height:
            even = image[:image.shape[0] // 2 * 2, :image.shape[1] // 2 * 2]
            image = cv2.resize(even, (even.shape[1] // 2, even.shape[0] // 2), interpolation=cv2.INTER_AREA)
    return cv2.resize(image, (width, height), dst=out, interpolation=cv2.INTER_LINEAR)


def preprocess(image: np.ndarray, config: PreprocessConfig, encoding: str = "rgb8",
               out: np.ndarray | None = None) -> np.ndarray:
    """Crop and resize one camera image to a uint8 [height, width, 3] RGB frame.

    `image` is H×W×3 (rgb8, bgr8) or H×W (mono8); rows may be strided (a view of a message buffer).
    Cropping first means only the kept rows are resized; the colour conversion happens after the
    resize, on the small frame, which gives the same result because the resize is per channel.
    """
    return finish(image[config.rows(image.shape[0])], config, encoding, out)


def finish(cropped: np.ndarray, config: PreprocessConfig, encoding: str = "rgb8",
           out: np.ndarray | None = None) -> np.ndarray:
    """`preprocess` after the crop: for readers that fetch only the kept rows."""
    if encoding == "rgb8":
        return resize(cropped, config.width, config.height, config.interpolation, out)
    small = resize(cropped, config.width, config.height, config.interpolation)
    if encoding == "bgr8":
        return cv2.cvtColor(small, cv2.COLOR_BGR2RGB, dst=out)
    if encoding == "mono8":
        return cv2.cvtColor(small, cv2.COLOR_GRAY2RGB, dst=out)
    raise PilotlabError(f"image encoding {encoding!r} is not supported; use one of {', '.join(ENCODINGS)}")


def to_input(frames: np.ndarray) -> torch.Tensor:
    """uint8 [N, H, W, 3] frames (or [N, F, H, W, 3] stacks, oldest first) -> float32 [N, 3F, H, W]
    in [0, 1], the network input (docs/CONVENTIONS.md)."""
    tensor = torch.from_numpy(np.ascontiguousarray(frames))
    if tensor.dim() == 4:
        tensor = tensor.unsqueeze(1)
    n, stack, height, width, _ = tensor.shape
    return tensor.permute(0, 1, 4, 2, 3).reshape(n, 3 * stack, height, width).float().div_(255.0)


class DrivePreprocessor:
    """Live camera image -> network input, as in training; keeps the last frames for temporal models.

    The first frames of a drive repeat the earliest frame, as `FrameSet.stack_index` does at the start
    of a recording.
    """

    def __init__(self, config: PreprocessConfig, ranges: LabelRanges, frames: int = 1):
        self.config, self.ranges, self.frames = config, ranges, frames
        self.history: deque[np.ndarray] = deque(maxlen=frames)

    @classmethod
    def from_checkpoint(cls, checkpoint: Mapping[str, Any]) -> DrivePreprocessor:
        """From the dict `pilotlab.models.load_checkpoint` returns (its "preprocess" and "labels")."""
        if not checkpoint.get("labels"):
            raise PilotlabError("checkpoint has no 'labels' ranges; it was not written by the train job")
        return cls.from_settings(checkpoint.get("preprocess") or {}, checkpoint["labels"])

    @classmethod
    def from_settings(cls, preprocess: Mapping[str, Any], labels: Mapping[str, Any]) -> DrivePreprocessor:
        """From a checkpoint's "preprocess" (PreprocessConfig fields, "frames", "frame_interval_s")
        and "labels"."""
        settings = dict(preprocess)
        frames = int(settings.pop("frames", 1))
        settings.pop("frame_interval_s", None)  # the brain's concern: how far apart stacked frames are
        config = PreprocessConfig.from_job_params(settings, "preprocess settings")
        return cls(config, LabelRanges.from_dict(labels), frames)

    def reset(self) -> None:
        """Forget earlier frames (call at the start of each drive)."""
        self.history.clear()

    def __call__(self, rgb: np.ndarray) -> torch.Tensor:
        """[1, 3 × frames, height, width] float32 for the latest camera image (uint8 H×W×3 RGB)."""
        frame = preprocess(rgb, self.config)
        if not self.history:
            self.history.extend([frame] * (self.frames - 1))
        self.history.append(frame)
        return to_input(np.stack(self.history)[None])

    def commands(self, outputs: torch.Tensor | np.ndarray | Sequence[float]) -> tuple[float, float]:
        """Physical (v m/s, w rad/s) from the network's normalised output for one image."""
        values = outputs.detach().cpu().numpy() if isinstance(outputs, torch.Tensor) else outputs
        v, w = self.ranges.denormalise(np.asarray(values, np.float32).reshape(-1, 2))[0]
        return float(v), float(w)
