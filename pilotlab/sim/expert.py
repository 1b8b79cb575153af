"""The expert driver: drives from the ground truth (the car's pose and the circuit), never the image.

Steering is pure pursuit on the red line (a target point a speed-dependent distance ahead of the rear
axle); speed follows a profile planned from the line's curvature (lateral acceleration limit, braking
before corners, acceleration after them). With noise, the expert now and then swerves: a random yaw
rate is added to what it applies for half a second or so, and it recovers by itself; the recorded
label stays the expert's clean command, so a dataset teaches how to come back to the line.
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
    version: int = 1


def speed_profile(circuit: Circuit, config: ExpertConfig) -> np.ndarray:
    """The planned speed at each centreline point: corners limit it, braking and acceleration
    limits spread the slow-downs before and the speed-ups after them."""
    spacing = circuit.length / len(circuit.points)
    curvature = np.abs(smooth_closed(circuit.curvature, 2.0 / spacing))
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
        self.profile = speed_profile(circuit, config)
        self._spacing = circuit.length / len(circuit.points)

    def target_speed(self, s: float) -> float:
        return float(np.interp(s % self.circuit.length, self.circuit.arc, self.profile, period=self.circuit.length))

    def act(self, info: dict[str, Any]) -> tuple[float, float]:
        if info["circuit"] != self.circuit.name or info["direction"] != self.circuit.direction:
            raise PilotlabError(f"this expert drives {self.circuit.name} {self.circuit.direction}, "
                                f"the env is on {info['circuit']} {info['direction']}")
        config = self.config
        x, y, yaw = info["pose"]
        speed = max(info["speed"], 0.0)
        v = self.target_speed(info["s"] + speed * config.speed_preview_s)
        rear_x, rear_y = x - config.wheelbase / 2 * math.cos(yaw), y - config.wheelbase / 2 * math.sin(yaw)
        lookahead = max(config.min_lookahead_m, speed * config.lookahead_s) + config.wheelbase / 2
        target_x, target_y = self.circuit.point_at(info["s"] + lookahead)
        dx, dy = target_x - rear_x, target_y - rear_y
        ahead = dx * math.cos(yaw) + dy * math.sin(yaw)
        left = -dx * math.sin(yaw) + dy * math.cos(yaw)
        curvature = 2 * left / max(ahead * ahead + left * left, 1e-6)
        return v, v * curvature


class Swerves:
    """Noise injection: occasional swerves added to the applied yaw rate.

    `noise` is the fraction of driving time spent swerving (0 = never, 0.1 = a tenth of the time). A
    swerve lasts 0.3 to 0.7 s at 0.4 to 0.9 rad/s either way, starts only when the car is within
    0.5 m of the line and stops early if it gets 1.5 m away, so the car never leaves the road."""

    def __init__(self, noise: float, rng: np.random.Generator):
        if not 0 <= noise < 1:
            raise PilotlabError(f"noise is the fraction of time spent swerving, in [0, 1); got {noise}")
        self.noise, self.rng = noise, rng
        self._left, self._rate = 0.0, 0.0

    def __call__(self, command: tuple[float, float], info: dict[str, Any], dt: float) -> tuple[float, float]:
        """The command to apply for the next `dt` seconds."""
        if self.noise <= 0:
            return command
        if self._left > 0 and abs(info["lateral_offset"]) > 1.5:
            self._left = 0.0
        if self._left <= 0 and abs(info["lateral_offset"]) < 0.5:
            mean_duration = 0.5
            if self.rng.random() < dt * self.noise / ((1 - self.noise) * mean_duration):
                self._left = self.rng.uniform(0.3, 0.7)
                self._rate = self.rng.choice((-1.0, 1.0)) * self.rng.uniform(0.4, 0.9)
        if self._left <= 0:
            return command
        self._left -= dt
        return command[0], command[1] + self._rate

    @property
    def swerving(self) -> bool:
        return self._left > 0
