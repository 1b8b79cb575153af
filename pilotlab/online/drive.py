"""The closed loop: a brain drives the car in a DrivingEnv under one of four timing modes.

    trajectory = drive(env, brain, DriveSettings(timing="replay"), start=0.0, latency_ms=samples)

Each brain iteration takes the camera image at the current simulated time, asks the brain for a
command, and advances the world. How far the world moves on, and with which command, is the timing
mode (`physics steps` are the env's 1/120 s):

- `replay` (default): an iteration costs max(control period, brain time) of simulated time, and
  the previous command stays in force for the brain time before the new one reaches the car, as on a
  real car: a slow network sees less often and reacts later. The brain time is a latency drawn
  (seeded by the run's seed) from `latency_ms`, the samples measured once for the same artifact on
  the same hardware profile (pilotlab.online.latency), plus `extra_latency_ms`, rounded up to whole
  physics steps (a command ready mid-step applies from the next one). Nothing of this host's wall
  clock enters the lap: the same lap on a loaded machine drives the same trajectory, and a lap can be
  driven for a device that is not this host. `fixed_inference_ms` replaces the draws with a constant
  ("what if this network took X ms").
- `measured`: as `replay`, but the brain time is the measured wall-clock time of the iteration on
  this host (preprocessing + inference), plus `extra_latency_ms`. Reproducible only while the brain
  takes less than one physics step (8.3 ms) or `fixed_inference_ms` pins it; otherwise it depends on
  the load (the measured times are kept in the trajectory).
- `lockstep`: the world waits for the brain: every iteration lasts one control period and the new
  command applies at once, whatever the brain costs (BehaviorMetrics with a paused Gazebo). Fully
  deterministic; latency has no effect on the driving.
- `realtime`: simulated time follows the wall clock, as Gazebo does: while the brain computes (and
  sleeps `extra_latency_ms`), the world moves on with the previous command; then the loop waits for
  the rest of the control period (BehaviorMetrics' 50 ms cycle) with the new command in force. Not
  reproducible, by nature.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pilotlab.errors import PilotlabError
from pilotlab.online.brains import Brain
from pilotlab.online.latency import LatencyDraws
from pilotlab.online.trajectory import Trajectory, TrajectoryBuilder
from pilotlab.sim.env import DrivingEnv
from pilotlab.specs.online import DriveSettings

FrameFn = Callable[[np.ndarray | None, dict[str, Any], tuple[float, float] | None], None]
ProgressFn = Callable[[float, float], None]   # (metres driven, metres to drive)


def _run_segments(env: DrivingEnv, segments: list[tuple[tuple[float, float], int]], render: bool):
    """Apply each (command, physics steps) in turn; the image is rendered after the last one only.
    Returns (obs, info, done); stops early when the episode ends."""
    segments = [(command, steps) for command, steps in segments if steps > 0]
    obs = info = None
    for i, (command, steps) in enumerate(segments):
        obs, _, terminated, truncated, info = env.step(command, duration=steps / env.physics_hz,
                                                       render=render and i == len(segments) - 1)
        if terminated or truncated:
            return obs, info, True
    return obs, info, False


class LatencyClock:
    def __init__(self, env: DrivingEnv, settings: DriveSettings):
        self.env, self.settings = env, settings
        self.period_steps = max(1, round(settings.period_s * env.physics_hz))

    def advance(self, previous, command, brain_s: float, render: bool):
        """(obs, info, done, simulated seconds before the command reached the car)."""
        settings = self.settings
        if settings.fixed_inference_ms is not None:
            brain_s = settings.fixed_inference_ms / 1000 + settings.extra_latency_ms / 1000
        # A command ready in the middle of a physics step applies from the next one (never earlier).
        late = math.ceil(brain_s * self.env.physics_hz - 1e-6)
        total = max(self.period_steps, late)
        obs, info, done = _run_segments(self.env, [(previous, late), (command, total - late)], render)
        return obs, info, done, late / self.env.physics_hz


class LockstepClock(LatencyClock):
    def advance(self, previous, command, brain_s: float, render: bool):
        obs, info, done = _run_segments(self.env, [(command, self.period_steps)], render)
        return obs, info, done, 0.0


class RealtimeClock(LatencyClock):
    """A cycle starts when the world is asked for the next camera image (rendering counts: it takes
    real time here, as a camera does on the car) and lasts at least one control period."""
    wall0 = cycle_start = 0.0

    def _catch_up(self, command, render: bool, minimum: int):
        """Step the world until simulated time has caught up with the wall clock."""
        behind = time.perf_counter() - self.wall0 - self.env.sim_time
        steps = max(minimum, round(behind * self.env.physics_hz))
        return _run_segments(self.env, [(command, steps)], render) + (steps,)

    def advance(self, previous, command, brain_s: float, render: bool):
        obs, info, done, late = self._catch_up(previous, False, 0)
        if done:
            return obs, info, done, late / self.env.physics_hz
        wait = self.cycle_start + self.settings.period_s - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        self.cycle_start = time.perf_counter()
        obs, info, done, _ = self._catch_up(command, render, 1)
        return obs, info, done, late / self.env.physics_hz


CLOCKS = {"replay": LatencyClock, "measured": LatencyClock, "lockstep": LockstepClock, "realtime": RealtimeClock}


def think(brain: Brain, obs, info: dict[str, Any], settings: DriveSettings,
          replayed_s: float | None = None) -> tuple[tuple[float, float], float, float]:
    """(command, brain_s, decision_s) of one brain iteration: the time of the whole iteration and the
    time of the decision the metrics report, both with the artificial latency (slept in realtime mode,
    where the world must move on meanwhile; added otherwise). Replayed, both are the replayed latency;
    otherwise the wall clock of this host."""
    extra_s = settings.extra_latency_ms / 1000
    started = time.perf_counter()
    command = brain.act(obs, info)
    if replayed_s is not None:
        return command, replayed_s + extra_s, replayed_s + extra_s
    if settings.timing == "realtime" and extra_s:
        time.sleep(extra_s)
    brain_s = time.perf_counter() - started + (0.0 if settings.timing == "realtime" else extra_s)
    decision = brain.last_inference_s if settings.fixed_inference_ms is None else settings.fixed_inference_ms / 1000
    return command, brain_s, decision + extra_s


def replay_source(settings: DriveSettings, latency_ms: np.ndarray | None, seed: int) -> Callable[[], float] | None:
    """What the replay mode charges each iteration (seconds, before the artificial latency)."""
    if settings.timing != "replay":
        return None
    if settings.fixed_inference_ms is not None:
        return lambda: settings.fixed_inference_ms / 1000
    if latency_ms is None:
        raise PilotlabError("the replay timing mode needs latency samples (the timing job's, or a "
                            "hardware profile's latency_file) or fixed_inference_ms; or use timing: measured")
    return LatencyDraws(latency_ms, seed).next_s


def drive(env: DrivingEnv, brain: Brain, settings: DriveSettings, *, start: float = 0.0, seed: int = 0,
          render: bool | None = None, on_frame: FrameFn | None = None,
          progress: ProgressFn | None = None, latency_ms: np.ndarray | None = None) -> Trajectory:
    """One run from `start` (metres along the lap) until the env stops it (lap completed, off the
    road, trapped, timeout). `render` (default: the brain needs the camera) renders the camera image
    every iteration; `on_frame(image, info, command)` sees each image with the command decided on it;
    `latency_ms`: the samples the replay mode draws from (seeded with `seed`)."""
    render = brain.needs_camera if render is None else render
    obs, info = env.reset(seed=seed, options={"start": start, "control_period": settings.period_s})
    if render and env.camera is None:
        raise PilotlabError(f"the {brain.name} brain needs the camera; make the DrivingEnv with a camera")
    brain.reset(env.circuit)
    replayed = replay_source(settings, latency_ms, seed)
    clock = CLOCKS[settings.timing](env, settings)
    builder = TrajectoryBuilder(env.circuit.length, {
        "circuit": env.circuit.name, "direction": env.circuit.direction, "start_m": float(start),
        "brain": brain.name, "label_ranges": getattr(brain, "label_ranges", None),
        **{k: getattr(settings, k) for k in DriveSettings.model_fields}})
    measured, previous, total = [], tuple(info["command"]), env.laps * env.circuit.length
    wall0 = clock.wall0 = clock.cycle_start = time.perf_counter()
    builder.sample(info, 0.0)
    done = False
    while not done:
        command, brain_s, decision_s = think(brain, obs, info, settings, replayed() if replayed else None)
        measured.append(brain.last_inference_s)
        if on_frame is not None:
            on_frame(obs, info, command)
        obs, info, done, charged = clock.advance(previous, command, brain_s, render)
        builder.decide(command, brain_s, decision_s, charged)
        builder.sample(info, time.perf_counter() - wall0)
        if progress is not None:
            progress(max(info["progress"], 0.0), total)
        previous = command
    return builder.build(termination=info["termination"], laps=env.laps, timeout_s=env.timeout_s,
                         measured_inference_ms=1000 * float(np.mean(measured)),
                         wall_seconds=time.perf_counter() - wall0, sim_seconds=info["sim_time"])
