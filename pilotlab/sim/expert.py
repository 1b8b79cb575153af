"""The expert driver: drives from the ground truth (the car's pose and the circuit), never the image.

Steering is pure pursuit on the red line (a target point a speed-dependent distance ahead of the rear
axle); speed follows a profile planned from the line's curvature (lateral acceleration limit, braking
before corners, acceleration after them), and eases off when it finds itself off the line (at speed,
pure pursuit back to the line would otherwise overshoot and slide). With noise (`Swerves`), the
expert now and then swerves off the line, where the road ahead leaves room for it, and comes back;
the recorded label stays the expert's clean command, so a dataset teaches how to return to the line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pilotlab.circuits import Circuit
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


class Expert:
    """(v, w) from the ground truth in the env's info dict."""

    def __init__(self, circuit: Circuit, config: ExpertConfig = ExpertConfig()):
        self.circuit, self.config = circuit, config
        self.profile, self.bend = speed_profile(circuit, config), bend(circuit)
        self._spacing = circuit.length / len(circuit.points)

    def target_speed(self, s: float) -> float:
        return float(np.interp(s % self.circuit.length, self.circuit.arc, self.profile, period=self.circuit.length))

    def act(self, info: dict[str, Any], offset: float = 0.0) -> tuple[float, float]:
        """The command for this state: pure pursuit on the red line, or with `offset` on the line
        shifted that many metres to the left (right if negative), as `Swerves` uses."""
        if info["circuit"] != self.circuit.name or info["direction"] != self.circuit.direction:
            raise PilotlabError(f"this expert drives {self.circuit.name} {self.circuit.direction}, "
                                f"the env is on {info['circuit']} {info['direction']}")
        config = self.config
        x, y, yaw = info["pose"]
        speed = max(info["speed"], 0.0)
        v = self.target_speed(info["s"] + speed * config.speed_preview_s)
        rear_x, rear_y = x - config.wheelbase / 2 * math.cos(yaw), y - config.wheelbase / 2 * math.sin(yaw)
        off_line = max(abs(info["lateral_offset"] - offset) - config.on_line_m, 0.0)
        v *= max(0.5, 1 - config.recovery_slowdown * off_line)
        lookahead = max(config.min_lookahead_m, speed * config.lookahead_s) + config.wheelbase / 2
        target_x, target_y = self.circuit.point_at(info["s"] + lookahead)
        if offset:
            heading = float(self.circuit.heading_at(info["s"] + lookahead))
            target_x, target_y = target_x - offset * math.sin(heading), target_y + offset * math.cos(heading)
        dx, dy = target_x - rear_x, target_y - rear_y
        ahead = dx * math.cos(yaw) + dy * math.sin(yaw)
        left = -dx * math.sin(yaw) + dy * math.cos(yaw)
        curvature = 2 * left / max(ahead * ahead + left * left, 1e-6)
        return v, v * curvature


@dataclass(frozen=True)
class SwerveConfig:
    """How the expert swerves when it records with noise (see `Swerves`)."""
    offset_m: tuple[float, float] = (0.5, 1.5)  # how far from the line a swerve drifts (either side)...
    edge_margin_m: float = 1.5       # ...never closer than this to the road edge
    lateral_accel: tuple[float, float] = (2.0, 4.0)  # m/s² a swerve's path may ask (sets its duration)...
    grip_budget: float = 8.0         # ...within what the road's own bend leaves of this (m/s², planned speed)
    min_radius_m: float = 10.0       # no swerve where the road bends tighter than this
    settle_s: float = 1.0            # after a swerve, at least this long before the next one
    start_within_m: float = 0.3      # a swerve starts only this close to the line...
    start_heading_rad: float = 0.1   # ...and this well aligned with it
    abort_margin_m: float = 1.0      # a swerve ends at once if the car would come this near the edge...
    abort_preview_s: float = 0.3     # ...this soon at its current heading
    version: int = 1


class Swerves:
    """Noise injection: the expert now and then swerves off the line and comes back.

    A swerve is a smooth excursion, out and back: the expert pursues the line shifted by
    `peak · (1 - cos(2π t / T)) / 2`, with a random peak of `offset_m` either side, and T as short as
    the lateral acceleration allowed for it permits (about 1.5 to 4 s). It is bounded by the road
    edge: the peak stays `edge_margin_m` inside it, and should the car head for the edge anyway the
    swerve ends at once and the expert recovers from there. It is bounded by the road ahead: it
    starts only when the car is back on the line, and must be over before the road bends tighter
    than `min_radius_m` or asks so much grip that less than `lateral_accel[0]` would be left of
    `grip_budget`; its acceleration is what the stretch leaves, and it shrinks to fit the room
    there is (`fit`), so no swerve starts in or just before a tight corner, where coming back would
    need more grip than the tyres have.

    `noise` is roughly the fraction of driving time spent swerving: swerves fall due at regular-ish
    intervals (at least `settle_s` apart); one that falls due where the road leaves no room waits for
    the next stretch that does, so twisty circuits get somewhat less (0.1 gives 5-8 % on the five
    built-in circuits). The label recorded stays the expert's clean command: frames during and after
    a swerve show the car off the line, heading away or back, with the command that returns it."""

    def __init__(self, noise: float, rng: np.random.Generator, expert: Expert,
                 config: SwerveConfig = SwerveConfig()):
        if not 0 <= noise < 1:
            raise PilotlabError(f"noise is the fraction of time spent swerving, in [0, 1); got {noise}")
        self.noise, self.rng, self.expert, self.config = noise, rng, expert, config
        self._demand = expert.profile ** 2 * expert.bend  # m/s² the road asks at the planned speed
        self._peak, self._duration, self._elapsed, self._due = 0.0, 0.0, 0.0, math.inf
        if noise > 0:
            self._schedule()

    @staticmethod
    def duration(peak: float, lateral_accel: float) -> float:
        """Seconds for an out-and-back excursion of `peak` metres whose path's lateral
        acceleration, peak · 2π² / T², is `lateral_accel`."""
        return math.pi * math.sqrt(2 * abs(peak) / lateral_accel)

    def __call__(self, command: tuple[float, float], info: dict[str, Any], dt: float) -> tuple[float, float]:
        """The command to apply for the next `dt` seconds (`command`: the expert's clean one)."""
        if not self.swerving:
            self._due -= dt
            if self._due <= 0:
                self._try_to_start(info)
        if self.swerving and self._heading_for_the_edge(info):
            self._schedule()
        if not self.swerving:
            return command
        self._elapsed += dt
        if self._elapsed >= self._duration:
            self._schedule()
            return command
        offset = self._peak * (1 - math.cos(2 * math.pi * self._elapsed / self._duration)) / 2
        return self.expert.act(info, offset=offset)

    @property
    def swerving(self) -> bool:
        return self._duration > 0

    def _schedule(self) -> None:
        """End any swerve and set when the next falls due (sooner by however long this one waited
        for a stretch that allowed it) and how far it goes."""
        config = self.config
        typical = self.duration(sum(config.offset_m) / 2, sum(config.lateral_accel) / 2)
        wait = typical * (1 - self.noise) / self.noise * self.rng.uniform(0.5, 1.5) + min(self._due, 0.0)
        self._due, self._duration, self._elapsed = max(wait, config.settle_s), 0.0, 0.0
        self._peak = self.rng.uniform(*config.offset_m) * float(self.rng.choice((-1.0, 1.0)))

    def fit(self, info: dict[str, Any], peak: float) -> tuple[float, float] | None:
        """The swerve of at most `peak` metres (signed) that may start now, as (peak, seconds): shrunk
        to stay `edge_margin_m` inside the road and to be over before the road ahead bends tighter
        than `min_radius_m` or leaves less than `lateral_accel[0]` of the grip budget, at the
        lateral acceleration that stretch leaves. None when not even `offset_m[0]` fits."""
        config, expert = self.config, self.expert
        low, high = config.lateral_accel
        reach = max(info["speed"], expert.config.top_speed) * self.duration(config.offset_m[1], low)
        ahead = self._points_ahead(info["s"], reach)
        blocked = (expert.bend[ahead] > 1 / config.min_radius_m) | (self._demand[ahead] > config.grip_budget - low)
        free = ahead[:int(np.argmax(blocked))] if blocked.any() else ahead
        if len(free) < 2:
            return None
        speed = max(info["speed"], float(expert.profile[free].max()))   # the fastest it goes through there
        seconds = len(free) * self.expert.circuit.length / len(expert.profile) / speed
        accel = min(high, config.grip_budget - float(self._demand[free].max()))
        size = min(abs(peak), info["road_width"] / 2 - config.edge_margin_m, accel * seconds ** 2 / (2 * math.pi ** 2))
        return (math.copysign(size, peak), self.duration(size, accel)) if size >= config.offset_m[0] else None

    def _points_ahead(self, s: float, metres: float) -> np.ndarray:
        """Indices of the centreline points from `s` to `metres` further on (wrapping round)."""
        circuit, count = self.expert.circuit, len(self.expert.profile)
        first = int(np.searchsorted(circuit.arc, s % circuit.length, side="right")) - 1
        return (first + np.arange(math.ceil(metres * count / circuit.length) + 1)) % count

    def _try_to_start(self, info: dict[str, Any]) -> None:
        config = self.config
        if abs(info["lateral_offset"]) > config.start_within_m or abs(info["heading_error"]) > config.start_heading_rad:
            return
        swerve = self.fit(info, self._peak)
        if swerve is not None:
            (self._peak, self._duration), self._elapsed = swerve, 0.0

    def _heading_for_the_edge(self, info: dict[str, Any]) -> bool:
        drift = max(info["speed"], 0.0) * math.sin(info["heading_error"]) * self.config.abort_preview_s
        limit = info["road_width"] / 2 - self.config.abort_margin_m
        return max(abs(info["lateral_offset"]), abs(info["lateral_offset"] + drift)) > limit
