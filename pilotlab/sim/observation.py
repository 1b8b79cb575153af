"""What DrivingEnv observes, as Gymnasium spaces: the camera image, the ground-truth state, or both.

- `"image"`: the camera image, `Box(0, 255, (height, width, 3), uint8)`, RGB (what a brain sees).
- `"state"`: `Box(float32, (8,))`, the ground truth a privileged policy may use (an RL teacher, the
  expert): `STATE_KEYS` in order, each clipped to its bounds so that every observation lies in the
  space (the lateral offset, for one, is unbounded once `stop_off_road=False`).
- `"image+state"`: `Dict({"image": ..., "state": ...})`.

The action space is `Box((v_min, w_min), (v_max, w_max), float32)` in m/s and rad/s: the car's
limits (`CarSpec.command_bounds`), or with `actions="normalized"` the same range mapped onto
[-1, 1]² (Gymnasium's checker and Stable-Baselines3 recommend a normalized range for learning).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces

from pilotlab.circuits.circuit import Circuit
from pilotlab.errors import PilotlabError
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.car import CarSpec

OBSERVATIONS = ("image", "state", "image+state")
ACTIONS = ("physical", "normalized")
CURVATURE_AHEAD_M = (0.0, 5.0, 10.0, 20.0)
# name: (low, high, meaning)
STATE_KEYS: dict[str, tuple[float, float, str]] = {
    "lateral_offset": (-20.0, 20.0, "metres from the red line, + left of the driving direction"),
    "heading_error": (-math.pi, math.pi, "car yaw minus the red line's heading, radians"),
    "speed": (-30.0, 30.0, "forward speed, m/s"),
    "yaw_rate": (-20.0, 20.0, "rad/s, + turning left"),
    **{f"curvature_{int(d)}m": (-2.0, 2.0, f"the red line's curvature {d:g} m ahead, 1/m, + turning left")
       for d in CURVATURE_AHEAD_M},
}


def check_observation(observation: str, camera: CameraSpec | None) -> str:
    if observation not in OBSERVATIONS:
        raise PilotlabError(f"unknown observation {observation!r}; use one of: {', '.join(OBSERVATIONS)}")
    if camera is None and observation != "state":
        raise PilotlabError(f"observation {observation!r} needs a camera; give camera=... or use "
                            "observation='state'")
    return observation


def image_space(camera: CameraSpec) -> spaces.Box:
    return spaces.Box(0, 255, (camera.height, camera.width, 3), np.uint8)


def state_space() -> spaces.Box:
    low, high = (np.array([bounds[i] for bounds in STATE_KEYS.values()], np.float32) for i in (0, 1))
    return spaces.Box(low, high, dtype=np.float32)


def observation_space(observation: str, camera: CameraSpec | None) -> spaces.Space:
    if observation == "image":
        return image_space(camera)
    if observation == "state":
        return state_space()
    return spaces.Dict({"image": image_space(camera), "state": state_space()})


def state_vector(info: dict[str, Any], circuit: Circuit) -> np.ndarray:
    """The ground-truth state of `STATE_KEYS`, clipped to its bounds."""
    curvature = [float(circuit.curvature_at((info["s"] + d) % circuit.length)) for d in CURVATURE_AHEAD_M]
    values = np.array([info["lateral_offset"], info["heading_error"], info["speed"], info["yaw_rate"], *curvature],
                      np.float32)
    space = state_space()
    return np.clip(values, space.low, space.high)


class ActionSpace:
    """The action space, and the physical (v, w) of an action from it."""

    def __init__(self, car: CarSpec, actions: str = "physical"):
        if actions not in ACTIONS:
            raise PilotlabError(f"unknown actions {actions!r}; use one of: {', '.join(ACTIONS)}")
        (v_min, v_max), (w_min, w_max) = car.command_bounds
        self.low, self.high = np.array([v_min, w_min], np.float32), np.array([v_max, w_max], np.float32)
        self.normalized = actions == "normalized"
        bound = np.ones(2, np.float32)
        self.space = spaces.Box(-bound, bound) if self.normalized else spaces.Box(self.low, self.high)

    def command(self, action) -> tuple[float, float]:
        """(v, w) in m/s and rad/s for `action`."""
        try:
            v, w = (float(a) for a in np.asarray(action, dtype=np.float64).reshape(2))
        except (TypeError, ValueError):
            raise PilotlabError(f"an action is two numbers (v, w), got {action!r}") from None
        if not (math.isfinite(v) and math.isfinite(w)):
            raise PilotlabError(f"the command must be finite numbers (v, w), got {action!r}")
        if self.normalized:
            v, w = (float(lo + (a + 1) / 2 * (hi - lo)) for a, lo, hi in zip((v, w), self.low, self.high))
        return v, w

    def action(self, v: float, w: float) -> np.ndarray:
        """The action that commands (v, w) (for a driver that thinks in m/s, like the expert)."""
        if not self.normalized:
            return np.array([v, w], np.float32)
        return ((np.array([v, w]) - self.low) / (self.high - self.low) * 2 - 1).astype(np.float32)
