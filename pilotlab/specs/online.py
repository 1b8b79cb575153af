"""The `online` job: a closed-loop evaluation of one brain on one circuit in the simulator, with
BehaviorMetrics' metrics. Exclusive when its clock is this host's (measured and realtime timing: see
`timed_live`), and asking Dask for a GPU when its hardware profile is a CUDA one.

deps: `artifact` (optional): the optimize job whose artifact the network brain runs; without it,
`brain` names a reference brain. `timing` (network brains, replay timing): the timing job of the
same artifact and hardware profile, whose latency samples the lap replays; `scale_reference` (with
latency_scale_to_ms): the baseline strategy's timing job on the same profile. inputs:
`latency_file` (optional): a device's latency file, replayed instead (pilotlab.online.latency).
The recipe's `online:` section and `pilotlab drive` share the lap settings below.
"""
from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from matrix.kinds import register_kind
from pilotlab.specs.base import (CONTROL_HZ, LATENCY_LIMIT_MS, CameraSize, Direction, InWorld, Spec,
                                 user_code_name)
from pilotlab.specs.timing import gpu_resources, timing_resources


# the timing modes that charge the brain's time to the lap (pilotlab.online.drive explains all four)
CHARGED = ("replay", "measured")
LATENCY_MODES = (*CHARGED, "realtime")   # where latency added to the brain's own delays its commands


class DriveSettings(Spec):
    """How simulated time advances around the brain (pilotlab.online.drive explains the modes)."""
    timing: Literal["replay", "measured", "lockstep", "realtime"] = Field(
        "replay", description="replay: each inference time, drawn from latencies measured once (the timing job's, "
                              "or a device's latency file), passes in simulated time with the previous command in "
                              "force; measured: the same with this host's wall clock; lockstep: the world waits "
                              "for the brain; realtime: simulated time follows the wall clock")
    control_hz: float = Field(CONTROL_HZ, gt=0, le=1000, description="brain iterations per simulated second when "
                                                                     "the brain keeps up")
    extra_latency_ms: float = Field(0.0, ge=0, le=LATENCY_LIMIT_MS,
                                    description="artificial latency added to every brain iteration (a slower network)")
    fixed_inference_ms: float | None = Field(None, ge=0, le=LATENCY_LIMIT_MS,
                                             description="replay and measured timing: charge this instead of the "
                                                         "brain's time (\"what if it took X ms\")")

    @model_validator(mode="after")
    def _fixed_needs_a_charged_mode(self):
        if self.fixed_inference_ms is not None and self.timing not in CHARGED:
            raise ValueError(f"fixed_inference_ms only means something in the {' and '.join(CHARGED)} timing "
                             f"modes, not {self.timing!r}")
        # a lockstep world waits for the brain: added latency changed nothing, yet the result said it was added
        if self.extra_latency_ms and self.timing == "lockstep":
            raise ValueError(f"extra_latency_ms means nothing in the lockstep timing mode (the world waits for the "
                             f"brain); use {', '.join(repr(m) for m in LATENCY_MODES)}")
        return self

    @property
    def period_s(self) -> float:
        return 1.0 / self.control_hz

    @property
    def drive(self) -> DriveSettings:
        return self


class ToleranceSpec(Spec):
    """The latency tolerance search of a lap cell (pilotlab.online.tolerance)."""
    # 50 ms is not among them: its lap was a whole lap of every cell (most keep 100 ms), and the search's
    # own laps put points between 0 and 100 where a cell's tolerance is there
    fixed_ms: list[float] = Field([0.0, 100.0, 200.0], description="injected latencies whose laps' deviation "
                                                                  "is reported (they also bracket the search; "
                                                                  "a search from a hint drives none)")
    max_ms: float = Field(1000.0, gt=0, le=LATENCY_LIMIT_MS, description="the largest injected latency searched")
    # 10 ms: the tolerance found for one network moved by 5-10 ms between the seeds of its latency draws
    # (study2022, 4 seeds, 2026-11-28), so a finer grid buys laps, not knowledge. Finer than 0.1 ms means
    # nothing (physics steps are 8.3 ms) and a tiny step overflowed the grid check.
    step_ms: float = Field(10.0, ge=0.1, description="the search's resolution (at least 0.1 ms)")
    # Past 0.5 because the two answers cost differently: a lost lap ends where the car leaves the road
    # (a fifth of a lap, typically), a completed one is a whole lap, slower than the plain one. The study's
    # 49 searched cells, their recorded laps replayed through the search (2026-11-28; a lap not driven costs
    # as its neighbours did): 0.5 (bisection) 22,905 simulated seconds, 0.6 21,056, 0.65 22,058, 0.7 20,966,
    # 0.75 21,256, 0.8 20,980; the same tolerances.
    probe: float = Field(0.7, ge=0.5, lt=1.0, description="where in the bracket the next lap is driven (0.5: "
                                                          "bisection; higher: fewer of the dear completed laps)")

    @property
    def bisection_laps(self) -> float:
        """About how many laps the bisection drives: log2 of the widest bracket of the fixed latencies
        over the step."""
        edges = sorted({0.0, *self.fixed_ms})
        widest = max((b - a for a, b in zip(edges, edges[1:])), default=self.max_ms)
        return math.log2(max(widest / self.step_ms, 1.0))

    @model_validator(mode="after")
    def _fixed_on_the_grid(self):
        if self.max_ms < self.step_ms or any(
                ms < 0 or ms > self.max_ms or abs(ms / self.step_ms - round(ms / self.step_ms)) > 1e-9
                for ms in self.fixed_ms):
            raise ValueError(f"fixed_ms {self.fixed_ms} must be multiples of step_ms ({self.step_ms:g}) between 0 and "
                             f"max_ms ({self.max_ms:g})")
        return self


class LapSettings(DriveSettings):
    laps: float = Field(1.0, gt=0, le=100, description="laps to drive")
    repetitions: int | None = Field(None, ge=1, le=1000, description="runs, each from its own start point "
                                                                      "(default 1, or one per start)")
    starts: Literal["spread", "random"] | list[float] = Field(
        "spread", description="spread: evenly round the lap (the first at the start line); random (from seed); "
                              "or metres along the lap, one per run")
    seed: int = Field(0, ge=0, lt=2**32)
    timeout_s: float | None = Field(None, gt=0, description="simulated seconds (default: BehaviorMetrics' "
                                                            "per-circuit timeout × laps)")
    stop_off_road: bool = Field(True, description="stop a run when the car's centre leaves the road")
    trapped_s: float = Field(10.0, gt=0, description="stop a run after this long without 1 m of progress")
    camera: CameraSize = CameraSize()
    renderer: Literal["ground", "pybullet"] = "ground"
    frame_interval_ms: float | None = Field(None, gt=0, description="temporal models: time between stacked "
                                                                    "frames (default: the training frames')")
    video: bool = Field(False, description="write camera.mp4, the first run's camera view")
    video_seconds: float = Field(20.0, gt=0, description="length of that video (simulated seconds)")
    camera_frames: int = Field(4, ge=0, le=1000, description="JPEG stills of the first run's camera view")
    tolerance: ToleranceSpec | None = Field(None, description="search the largest injected latency at which the lap "
                                                              "is still completed (true: the default search)")
    latency_scale_to_ms: float | None = Field(None, gt=0, description="replay: scale every latency by one factor so "
                                                                      "the baseline's median is this (a slower device)")

    @field_validator("tolerance", mode="before")
    @classmethod
    def _true_is_the_default_search(cls, value: Any) -> Any:
        if value is not None and not isinstance(value, (bool, dict, ToleranceSpec)):
            raise ValueError(f"tolerance is true (the default search), false, or a mapping of the search's "
                             f"settings ({', '.join(ToleranceSpec.model_fields)}); got {value!r}")
        return {} if value is True else None if value is False else value

    @model_validator(mode="after")
    def _a_tolerance_needs_latency_to_count(self):
        # outside test: in lockstep every lap of the search was completed, and the search reported 1000 ms
        if self.tolerance is not None and self.timing == "lockstep":
            raise ValueError(f"a latency tolerance search means nothing in the lockstep timing mode (the world waits "
                             f"for the brain, so every latency keeps the lap); use "
                             f"{', '.join(repr(m) for m in LATENCY_MODES)}")
        return self

    @model_validator(mode="after")
    def _one_start_per_run(self):
        if isinstance(self.starts, list) and self.repetitions not in (None, len(self.starts)):
            raise ValueError(f"starts lists {len(self.starts)} point(s) but repetitions is {self.repetitions}; "
                             "give one start point per repetition")
        return self

    @property
    def runs(self) -> int:
        return self.repetitions or (len(self.starts) if isinstance(self.starts, list) else 1)

    @property
    def video_length_s(self) -> float | None:
        return self.video_seconds if self.video else None


class UserBrainSpec(Spec):
    """A brain the user wrote (docs/brains.md). Its source hash is the job's input `brain_source`
    (pilotlab.usercode.source_hash: the file and the local modules it imports), so an edit reruns it."""
    name: str = Field(min_length=1, description="the report row's name")
    spec: str = Field(description="file.py:Class or module:Class")
    base: str = Field(".", description="the folder a relative file is in, for a job without the input "
                                       "brain_source (`drive --brain`: the current one); a recipe's lap finds "
                                       "it from that input, so that a moved project keeps its laps")

    @field_validator("spec")
    @classmethod
    def _spec_named(cls, spec):
        return user_code_name(spec)


class OnlineSpec(LapSettings, InWorld):
    circuit: str = Field(min_length=1, description="circuit name (built-in, ./circuits/NAME.csv) or CSV path")
    direction: Direction = "cw"
    brain: str = Field("network", description='"network" (runs the artifact dependency) | "explicit" (OpenCV '
                                              'line follower) | "expert" (ground truth): the reference rows | '
                                              '"user": a brain the user wrote, `user_brain`')
    brain_options: dict[str, Any] = Field({}, description="fields of the reference brain's config")
    user_brain: UserBrainSpec | None = Field(None, description="with brain 'user': which class")
    hardware: dict[str, Any] = Field({"name": "cpu"}, description='the profile {"name", "device", "threads"}')
    host: dict[str, Any] | None = Field(None, description="the host the planner expects; another is an error")
    latency_for: dict[str, str] = Field({}, description='{"model", "strategy"}: the rows of the latency file to replay')
    version: int = 1

    @model_validator(mode="after")
    def _user_brain_with_brain_user(self):
        if (self.brain == "user") != (self.user_brain is not None):
            raise ValueError("brain 'user' and user_brain go together: give both or neither")
        return self


def timed_live(params) -> bool:
    """A lap whose clock is this host's (measured, realtime) needs the host to itself; replayed and
    lockstep laps do not depend on its load, so they run beside other jobs (the study's hundreds of
    tolerance laps ran one at a time on a 2-core machine before)."""
    return params.get("timing", DriveSettings.model_fields["timing"].default) in ("measured", "realtime")


def lap_resources(params) -> dict[str, float]:
    """A lap runs its network on the profile's device (a GPU for CUDA); it needs the profile's machine
    itself only where the lap reads its clock: a replayed lap replays that machine's timings anywhere."""
    return timing_resources(params) if timed_live(params) else gpu_resources(params)


register_kind("online", "pilotlab.jobs.online:run_online", params=OnlineSpec, exclusive_for=timed_live,
              resources_for=lap_resources)
