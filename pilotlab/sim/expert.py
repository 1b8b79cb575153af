"""The expert driver: drives from the ground truth (the car's pose and the circuit), never the image.

Steering is pure pursuit on the red line (a target point a speed-dependent distance ahead of the rear
axle); speed follows a profile planned from the line's curvature (lateral acceleration limit, braking
before corners, acceleration after them), and eases off when it finds itself off the line (at speed,
pure pursuit back to the line would otherwise overshoot and slide). With noise (`Swerves`), a random
yaw rate is now and then added to what it applies, within what the road leaves room and grip for,
and it recovers by itself; the recorded label stays the expert's clean command, so a dataset
teaches how to return to the line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.circuits.geometry import smooth_closed
from pilotlab.errors import PilotlabError


@dataclass(frozen=True)
class ExpertConfig:
    top_speed: float = 13.0          # m/s
    lateral_accel: float = 5.5       # m/s², planned through corners
    braking: float = 4.0             # m/s², planned (the car can do about 8)
    acceleration: float = 3.5        # m/s², planned (the car can do about 4.4)
    min_speed: float = 3.0
    lookahead_s: float = 0.25        # pure-pursuit look-ahead time...
    min_lookahead_m: float = 2.0     # ...but never shorter than this
    speed_preview_s: float = 0.4     # the speed target is read this far ahead
    wheelbase: float = 1.6
    recovery_slowdown: float = 0.3   # off the line, it slows by this fraction per metre beyond...
    on_line_m: float = 0.25          # ...this (pure pursuit oscillates and the tyres slide at speed)
    version: int = 1


# The expert of BM's worlds drives BM's small F1 (pilotlab.sim.car.BM_F1): its wheelbase, a gentler pace.
BM_EXPERT = {"wheelbase": 0.64, "top_speed": 8.0, "min_lookahead_m": 1.0}


def bend(circuit: Circuit) -> np.ndarray:
    """|curvature| at each centreline point, smoothed over 2 m: what a car actually has to turn."""
    return np.abs(smooth_closed(circuit.curvature, 2.0 / (circuit.length / len(circuit.points))))


def speed_profile(circuit: Circuit, config: ExpertConfig) -> np.ndarray:
    """The planned speed at each centreline point: corners limit it, braking and acceleration
    limits spread the slow-downs before and the speed-ups after them."""
    spacing = circuit.length / len(circuit.points)
    curvature = bend(circuit)
    speed = np.minimum(config.top_speed, np.sqrt(config.lateral_accel / np.maximum(curvature, 1e-6)))
    speed = np.maximum(speed, config.min_speed)
    for _ in range(2):  # twice around: the limits wrap over the start line
        for i in range(len(speed) - 1, -1, -1):
            speed[i] = min(speed[i], math.sqrt(speed[(i + 1) % len(speed)] ** 2 + 2 * config.braking * spacing))
        for i in range(len(speed)):
            speed[i] = min(speed[i], math.sqrt(speed[i - 1] ** 2 + 2 * config.acceleration * spacing))
    return speed


def periodic_table(xp: np.ndarray, fp: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """The padded table np.interp(..., period=period) builds on every call."""
    xp = np.asarray(xp, np.float64) % period
    order = np.argsort(xp)
    xp, fp = xp[order], np.asarray(fp, np.float64)[order]
    return np.concatenate((xp[-1:] - period, xp, xp[0:1] + period)), np.concatenate((fp[-1:], fp, fp[0:1]))


class Expert:
    """(v, w) from the ground truth in the env's info dict."""

    def __init__(self, circuit: Circuit, config: ExpertConfig = ExpertConfig()):
        self.circuit, self.config = circuit, config
        self.profile, self.bend = speed_profile(circuit, config), bend(circuit)
        self._spacing = circuit.length / len(circuit.points)
        self._profile_xp, self._profile_fp = periodic_table(circuit.arc, self.profile, circuit.length)

    def target_speed(self, s: float) -> float:
        # np.interp(s % length, arc, profile, period=length), its periodic table built once, not per call
        length = self.circuit.length
        return float(np.interp((s % length) % length, self._profile_xp, self._profile_fp))

    def act(self, info: dict[str, Any]) -> tuple[float, float]:
        """The command for this state: pure pursuit on the red line."""
        if info["circuit"] != self.circuit.name or info["direction"] != self.circuit.direction:
            raise PilotlabError(f"this expert drives {self.circuit.name} {self.circuit.direction}, "
                                f"the env is on {info['circuit']} {info['direction']}")
        config = self.config
        x, y, yaw = info["pose"]
        speed = max(info["speed"], 0.0)
        v = self.target_speed(info["s"] + speed * config.speed_preview_s)
        rear_x, rear_y = x - config.wheelbase / 2 * math.cos(yaw), y - config.wheelbase / 2 * math.sin(yaw)
        off_line = max(abs(info["lateral_offset"]) - config.on_line_m, 0.0)
        v *= max(0.5, 1 - config.recovery_slowdown * off_line)
        lookahead = max(config.min_lookahead_m, speed * config.lookahead_s) + config.wheelbase / 2
        target_x, target_y = self.circuit.point_at(info["s"] + lookahead)
        dx, dy = target_x - rear_x, target_y - rear_y
        ahead = dx * math.cos(yaw) + dy * math.sin(yaw)
        left = -dx * math.sin(yaw) + dy * math.cos(yaw)
        curvature = 2 * left / max(ahead * ahead + left * left, 1e-6)
        return v, v * curvature


@dataclass(frozen=True)
class SwerveConfig:
    """How the expert swerves when it records with noise (see `Swerves`)."""
    rate_rad_s: tuple[float, float] = (0.4, 0.9)   # yaw rate added to the expert's, either way...
    duration_s: tuple[float, float] = (0.3, 0.7)   # ...for this long
    grip_budget: float = 8.0         # m/s²: the road's own bend plus the swerve's v·rate stay within this...
    min_rate_rad_s: float = 0.25     # ...and where that leaves less than this, no swerve
    settle_s: float = 1.0            # after a swerve, at least this long before the next one
    start_within_m: float = 0.5      # a swerve starts only this close to the line...
    start_heading_rad: float = 0.15  # ...and this well aligned with it
    max_offset_m: float = 1.5        # a swerve ends once this far from the line...
    abort_margin_m: float = 1.0      # ...or if the car would come this near the road edge...
    abort_preview_s: float = 0.3     # ...this soon at its current heading
    version: int = 2


class Swerves:
    """Noise injection: now and then a random yaw rate is added to the expert's for half a second
    or so, and the expert recovers by itself.

    The label recorded stays the expert's clean command, so a dataset shows the car off the line and
    askew, with the command that brings it back: the recoveries a network cannot learn from clean
    laps. `noise` is roughly the fraction of driving time spent swerving (0.1: a tenth).

    A swerve is bounded so the car never leaves the road: it starts only when the car is near the
    line and aligned with it, at least `settle_s` after the last one; its rate is cut so the lateral
    acceleration it adds (v · rate) fits in what the road's own bend leaves of `grip_budget` (so in a
    tight corner at speed it is small or none at all); and it ends early once the car is
    `max_offset_m` from the line or heading for the edge."""

    def __init__(self, noise: float, rng: np.random.Generator, expert: Expert,
                 config: SwerveConfig = SwerveConfig()):
        if not 0 <= noise < 1:
            raise PilotlabError(f"noise is the fraction of time spent swerving, in [0, 1); got {noise}")
        self.noise, self.rng, self.expert, self.config = noise, rng, expert, config
        self._left, self._rate, self._settle = 0.0, 0.0, 0.0

    def __call__(self, command: tuple[float, float], info: dict[str, Any], dt: float) -> tuple[float, float]:
        """The command to apply for the next `dt` seconds (`command`: the expert's clean one)."""
        if self.swerving and self._too_far(info):
            self._end()
        if not self.swerving:
            self._settle -= dt
            if self._settle <= 0 and self._falls_due(dt):
                self._try_to_start(info)
        if not self.swerving:
            return command
        self._left -= dt
        if self._left <= 0:
            self._end()
        return command[0], command[1] + self._rate

    @property
    def swerving(self) -> bool:
        return self._left > 0

    def _falls_due(self, dt: float) -> bool:
        """A Poisson draw whose rate makes swerves take about `noise` of the time."""
        mean = sum(self.config.duration_s) / 2
        return self.noise > 0 and self.rng.random() < dt * self.noise / ((1 - self.noise) * mean)

    def allowed_rate(self, info: dict[str, Any]) -> float:
        """The largest yaw rate a swerve may add here: what the bend leaves of the grip budget."""
        speed = max(info["speed"], 1.0)
        demand = speed * speed * float(np.interp(info["s"] % self.expert.circuit.length, self.expert.circuit.arc,
                                                 self.expert.bend, period=self.expert.circuit.length))
        return max(self.config.grip_budget - demand, 0.0) / speed

    def _try_to_start(self, info: dict[str, Any]) -> None:
        config = self.config
        if abs(info["lateral_offset"]) > config.start_within_m or abs(info["heading_error"]) > config.start_heading_rad:
            return
        rate = min(self.rng.uniform(*config.rate_rad_s), self.allowed_rate(info))
        if rate >= config.min_rate_rad_s:
            self._rate = rate * float(self.rng.choice((-1.0, 1.0)))
            self._left = self.rng.uniform(*config.duration_s)

    def _end(self) -> None:
        self._left, self._settle = 0.0, self.config.settle_s

    def _too_far(self, info: dict[str, Any]) -> bool:
        config = self.config
        drift = max(info["speed"], 0.0) * math.sin(info["heading_error"]) * config.abort_preview_s
        edge = info["road_width"] / 2 - config.abort_margin_m
        offset = abs(info["lateral_offset"])
        return offset > config.max_offset_m or max(offset, abs(info["lateral_offset"] + drift)) > edge
