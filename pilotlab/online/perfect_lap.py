"""The "perfect lap" BehaviorMetrics scores a run against: the expert brain's lap on the same circuit
and direction, driven here (deterministically: lockstep timing, from the start line, no camera; a
few seconds even on montreal), one checkpoint per sample at CONTROL_HZ. It is the expert's second
lap, a flying one: the first starts from a standstill, and its close-packed checkpoints there would
weigh the start line more than the rest of the circuit.

    checkpoints = perfect_lap("montreal", "cw")     # [M, 2] metres, in driving order
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from matrix.fingerprint import closure_fingerprint, module_closure
from pilotlab.errors import PilotlabError
from pilotlab.online.brains import make_reference_brain
from pilotlab.online.drive import drive
from pilotlab.sim.env import DrivingEnv
from pilotlab.specs.online import DriveSettings

# BehaviorMetrics' perfect laps are odometry recordings; ours samples the expert at the 50 ms cycle,
# whatever the evaluated lap's control rate, so the checkpoints (and the deviation total) do not move
# with it.
CONTROL_HZ = 20.0


def perfect_lap(circuit: str, direction: str = "cw", cache: Path | None = None) -> np.ndarray:
    """The checkpoints [M, 2]; with `cache` (a folder), kept there under a key of the circuit's points,
    the direction and the code that drives it, so the jobs of one store drive it once."""
    if cache is None:
        return _drive_perfect_lap(circuit, direction)
    from pilotlab.circuits.load import get_circuit
    driven = get_circuit(circuit, direction)
    path = Path(cache) / f"perfect_lap_{_key(driven.points, driven.road_width)}.npy"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(f".{os.getpid()}.tmp.npy")
        np.save(partial, _drive_perfect_lap(circuit, direction))
        os.replace(partial, path)
    return np.load(path)


def _key(points: np.ndarray, road_width: float) -> str:
    """The circuit's points and road width, and the code that drives the lap: this module's import closure
    within pilotlab, computed (a hand-kept list of modules missed the expert's brain and its smoothing)."""
    digest = hashlib.sha256(np.ascontiguousarray(points, np.float64).tobytes() + f"{road_width} {CONTROL_HZ}".encode())
    digest.update(closure_fingerprint(module_closure(__name__, "pilotlab")).encode())
    return digest.hexdigest()[:20]


def _drive_perfect_lap(circuit: str, direction: str) -> np.ndarray:
    env = DrivingEnv(circuit, direction=direction, camera=None, control_period=1 / CONTROL_HZ, laps=2)
    try:
        trajectory = drive(env, make_reference_brain("expert"), DriveSettings(timing="lockstep", control_hz=CONTROL_HZ))
    finally:
        env.close()
    if trajectory.termination != "lap_completed":
        raise PilotlabError(f"the expert's perfect lap of {circuit} {direction} ended {trajectory.termination}; "
                            "BehaviorMetrics' metrics need one completed lap (is the circuit drivable?)")
    return flying_lap(trajectory)


def flying_lap(trajectory) -> np.ndarray:
    """The positions [M, 2] of the samples of the second lap (progress from one circuit length to two)."""
    second = (trajectory.progress >= trajectory.circuit_length) & (trajectory.progress < 2 * trajectory.circuit_length)
    return np.stack([trajectory.x[second], trajectory.y[second]], axis=1)
