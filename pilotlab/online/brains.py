"""Brains: what turns the car's camera image (or, for the expert, the ground truth) into (v, w).

    brain = NetworkBrain(load_predictor(artifact_dir, "cpu1"))     # any optimized artifact
    brain = make_reference_brain("explicit")                      # the OpenCV line follower
    brain = make_reference_brain("expert")                        # the ground-truth driver
    brain = UserBrain("brains/mine.py:MyBrain", base=Path.cwd())  # a brain the user wrote
    brain.reset(env.circuit); v, w = brain.act(image, info)

A network brain feeds the network exactly what training saw: `pilotlab.data.preprocess` on the
camera image with the artifact's preprocessing settings, `to_input`'s float layout, and the
artifact's label ranges to de-normalise the output. Temporal models get their stacked frames, picked
`frame_interval_s` apart in simulated time (the spacing of consecutive recorded frames in training).

Every brain sets `last_inference_s` after each `act`: the time of the decision itself (the network's
predict call; a reference brain's whole computation), which the metrics report.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from matrix.registry import Registry
from pilotlab.circuits.circuit import Circuit
from pilotlab.data.frames import LabelRanges
from pilotlab.data.preprocess import PreprocessConfig, preprocess
from pilotlab.errors import PilotlabError
from pilotlab.specs.base import build_config
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.expert import Expert, ExpertConfig
from pilotlab.sim.explicit import ExplicitBrain, ExplicitBrainConfig

# The record job's default camera rate is 10 Hz: consecutive training frames are 0.1 s apart.
DEFAULT_FRAME_INTERVAL_S = 0.1


class Brain(Protocol):
    name: str
    needs_camera: bool
    last_inference_s: float

    def reset(self, circuit: Circuit) -> None: ...

    def act(self, image: np.ndarray | None, info: dict[str, Any]) -> tuple[float, float]: ...

    def warm_up(self) -> None: ...


class FrameStack:
    """The frames a temporal model sees: the newest and its predecessors `interval_s` apart in
    simulated time (oldest first). Before enough history exists, the earliest frame is repeated, as
    `FrameSet.stack_index` does at the start of a recording."""

    def __init__(self, frames: int, interval_s: float):
        if frames < 1 or interval_s <= 0:
            raise PilotlabError(f"a frame stack needs frames >= 1 and a positive interval, got {frames}, {interval_s}")
        self.frames, self.interval_s = frames, interval_s
        self.reset()

    def reset(self) -> None:
        self.times: list[float] = []
        self.images: list[np.ndarray] = []

    def push(self, frame: np.ndarray, t: float) -> np.ndarray:
        """Add the frame seen at simulated time `t`; returns [frames, H, W, 3] (oldest first)."""
        self.times.append(t)
        self.images.append(frame)
        horizon = t - self.frames * self.interval_s
        while len(self.times) > 1 and self.times[1] <= horizon:
            self.times.pop(0)
            self.images.pop(0)
        targets = t - self.interval_s * np.arange(self.frames - 1, -1, -1)
        times = np.asarray(self.times)
        # The nearest frame to each target time (ties go to the later one).
        picks = [len(times) - 1 - int(np.argmin(np.abs(times[::-1] - target))) for target in targets]
        return np.stack([self.images[i] for i in picks])


class NetworkBrain:
    """Runs an optimized artifact through the uniform predictor on the camera image."""
    needs_camera = True

    def __init__(self, predictor, frame_interval_s: float | None = None):
        meta = predictor.meta
        self.predictor, self.name = predictor, meta.strategy
        if not meta.labels:
            raise PilotlabError(f"artifact {meta.strategy}: its artifact.json has no label ranges; "
                                "rerun the optimize job on a checkpoint written by the train job")
        self.ranges = LabelRanges.from_dict(meta.labels)
        self.label_ranges = self.ranges.as_dict()   # BehaviorMetrics' suddenness is on normalised outputs
        self.config = PreprocessConfig.from_params(meta.preprocess)
        self.frames = self._check_input(meta)
        interval = frame_interval_s or meta.preprocess.get("frame_interval_s") or DEFAULT_FRAME_INTERVAL_S
        self.stack = FrameStack(self.frames, float(interval))
        self.last_inference_s = 0.0

    def _check_input(self, meta) -> int:
        channels, height, width = meta.input_shape[1:]
        frames = int(meta.preprocess.get("frames", channels // 3))
        if (height, width) != (self.config.height, self.config.width) or channels != 3 * frames:
            raise PilotlabError(
                f"artifact {meta.strategy}: the network takes [N, {channels}, {height}, {width}] but its preprocessing "
                f"makes {frames} frame(s) of {self.config.height}x{self.config.width}; the checkpoint's 'preprocess' "
                "does not match its model; retrain it with the train job")
        return frames

    def reset(self, circuit: Circuit) -> None:
        self.stack.reset()

    def warm_up(self, runs: int = 5) -> None:
        """A few predictions on a blank input: the first calls allocate and pick kernels."""
        blank = np.zeros((1, 3 * self.frames, self.config.height, self.config.width), np.float32)
        for _ in range(runs):
            self.predictor.predict(blank)

    @property
    def view(self) -> PreprocessConfig:
        """What the env may render instead of the camera image (DrivingEnv's `view`): the network's
        preprocessed frame, drawn directly."""
        return self.config

    def inputs(self, image: np.ndarray, t: float, rendered_view=None) -> np.ndarray:
        """The network's input for the camera image seen at simulated time `t`; when the env rendered
        this brain's view (`rendered_view` is its config) the image is already the preprocessed frame."""
        frame = image if rendered_view == self.config else preprocess(image, self.config)
        stack = self.stack.push(frame, t)
        # `to_input`'s layout and arithmetic (uint8 -> float32, / 255) in numpy: torch's per-call
        # overhead on one small frame costs more than the conversion itself
        frames, height, width, _ = stack.shape
        channels_first = stack.transpose(0, 3, 1, 2).reshape(1, 3 * frames, height, width)
        return channels_first.astype(np.float32) / np.float32(255.0)

    def act(self, image: np.ndarray | None, info: dict[str, Any]) -> tuple[float, float]:
        if image is None:
            raise PilotlabError("a network brain needs the camera image; the env was made without a camera")
        inputs = self.inputs(image, info["sim_time"], info.get("view"))
        started = time.perf_counter()
        output = self.predictor.predict(inputs)
        self.last_inference_s = time.perf_counter() - started
        v, w = self.ranges.denormalise(np.asarray(output, np.float32).reshape(-1, 2))[0]
        return float(v), float(w)


class ExplicitReference:
    """The OpenCV red-line follower (pilotlab.sim.explicit), timed as a brain. In a closed loop it is
    given its `view`: the rows of the camera frame its bands look at (the lower half, when they are
    all below the horizon), at half resolution, rendered directly (pilotlab.sim.view), a sixth of the
    full 640×480 frame's pixels; it reads the full frame when given one."""
    needs_camera = True

    def __init__(self, config: ExplicitBrainConfig):
        self.name, self.brain, self.last_inference_s = "explicit", ExplicitBrain(config), 0.0
        top = 0.5 if self.brain.top_row >= 0.5 else 0.0
        camera = CameraSpec()   # the default frame, 640×480
        self.view = PreprocessConfig(crop_top=top, crop_bottom=1.0, width=camera.width // 2,
                                     height=round(camera.height * (1 - top) / 2), interpolation="fast_area")

    def reset(self, circuit: Circuit) -> None:
        self.brain.reset()

    def warm_up(self) -> None:
        pass

    def act(self, image: np.ndarray | None, info: dict[str, Any]) -> tuple[float, float]:
        started = time.perf_counter()
        shown = (self.view.crop_top, self.view.crop_bottom) if info.get("view") == self.view else (0.0, 1.0)
        command = self.brain.act(image, shown)
        self.last_inference_s = time.perf_counter() - started
        return command


class ExpertReference:
    """The ground-truth expert (pilotlab.sim.expert): the best a driver of this car can do."""
    needs_camera = False

    def __init__(self, config: ExpertConfig):
        self.name, self.config, self.expert, self.last_inference_s = "expert", config, None, 0.0

    def reset(self, circuit: Circuit) -> None:
        self.expert = Expert(circuit, self.config)

    def warm_up(self) -> None:
        pass

    def act(self, image: np.ndarray | None, info: dict[str, Any]) -> tuple[float, float]:
        started = time.perf_counter()
        command = self.expert.act(info)
        self.last_inference_s = time.perf_counter() - started
        return command


@dataclass(frozen=True)
class ReferenceEntry:
    name: str
    config_cls: type
    factory: Callable[[Any], Brain]
    doc: str


REFERENCE_BRAINS: Registry[ReferenceEntry] = Registry("reference brain")
REFERENCE_BRAINS.add("explicit", ReferenceEntry("explicit", ExplicitBrainConfig, ExplicitReference,
                                                "follows the red line in the camera image with OpenCV"))
REFERENCE_BRAINS.add("expert", ReferenceEntry("expert", ExpertConfig, ExpertReference,
                                              "drives from the ground truth (pure pursuit + speed profile)"))


def make_reference_brain(name: str, options: dict[str, Any] | None = None) -> Brain:
    """A reference brain by name, its config fields overridden by `options`."""
    entry = REFERENCE_BRAINS.get(name)
    config = build_config(entry.config_cls, options, f"brain_options of the {name} brain")
    return entry.factory(config)


class UserBrain:
    """A brain the user wrote: any class with `act(image) -> (v, w)` (the camera image, RGB uint8
    H×W×3, the full frame as the explicit brain gets it) and optionally `reset()`, called before each
    run. Named `file.py:Class` (relative to `base`) or `module:Class`; `options` go to its constructor.
    An exception in the user's code, or a command that is not two finite numbers, is one line naming
    the file and line (pilotlab.usercode)."""
    needs_camera = True

    def __init__(self, spec: str, base: Path, name: str | None = None, options: dict[str, Any] | None = None):
        from pilotlab import usercode
        self.spec, self.last_inference_s = spec, 0.0
        found = usercode.load_object(spec, base)
        self.name = name or spec.rpartition(":")[2]
        try:
            self.brain = found(**(options or {})) if isinstance(found, type) else found
        except Exception as error:
            raise usercode.UserCodeError(f"{usercode.error_line(error, spec)} (making {spec})") from None
        if not callable(getattr(self.brain, "act", None)):
            raise usercode.UserCodeError(f"{spec}: has no act(image) method; a brain's act(image) returns (v, w)")

    def reset(self, circuit: Circuit) -> None:
        if callable(getattr(self.brain, "reset", None)):
            self._call("reset")

    def warm_up(self) -> None:
        pass

    def act(self, image: np.ndarray | None, info: dict[str, Any]) -> tuple[float, float]:
        if image is None:
            raise PilotlabError(f"the {self.name} brain needs the camera image; the env was made without a camera")
        started = time.perf_counter()
        command = self._call("act", image)
        self.last_inference_s = time.perf_counter() - started
        return self._check(command)

    def _call(self, method: str, *args):
        from pilotlab import usercode
        try:
            return getattr(self.brain, method)(*args)
        except Exception as error:
            raise usercode.UserCodeError(f"{usercode.error_line(error, self.spec)} (in {self.spec}.{method})") from None

    def _check(self, command) -> tuple[float, float]:
        try:
            values = np.asarray(command)
            if values.dtype.kind not in "biuf":   # text ("5", "0") or objects: not numbers, however they read
                raise TypeError(values.dtype)
            v, w = (float(c) for c in values.astype(np.float64).reshape(2))   # [2] or [1, 2]: a network's output
        except (TypeError, ValueError, RuntimeError):   # RuntimeError: a tensor that requires grad
            v = w = float("nan")
        if not (np.isfinite(v) and np.isfinite(w)):
            from pilotlab import usercode
            raise PilotlabError(f"{usercode.returned_at(self.brain.act, self.spec)}: act returned {command!r}; it "
                                f"must return (v, w), two finite numbers (m/s and rad/s) (in {self.spec}.act)")
        return v, w
