"""The "perfect lap" BehaviorMetrics scores a run against: the expert brain's lap on the same circuit
and direction, driven here (deterministically: lockstep timing, from the start line, no camera; a
couple of seconds even on montreal), one checkpoint per sample at CONTROL_HZ.

    checkpoints = perfect_lap("montreal", "cw")     # [M, 2] metres, in driving order
"""
from __future__ import annotations

import numpy as np

from pilotlab.errors import PilotlabError
from pilotlab.online.bm_metrics import perfect_lap_checkpoints
from pilotlab.online.brains import make_reference_brain
from pilotlab.online.drive import DriveSettings, drive
from pilotlab.sim.env import DrivingEnv

# BehaviorMetrics' perfect laps are odometry recordings; ours samples the expert at the 50 ms cycle,
# whatever the evaluated lap's control rate, so the checkpoints (and the deviation total) do not move
# with it.
CONTROL_HZ = 20.0


def perfect_lap(circuit: str, direction: str = "cw") -> np.ndarray:
    env = DrivingEnv(circuit, direction=direction, camera=None, control_period=1 / CONTROL_HZ, laps=1)
    try:
        trajectory = drive(env, make_reference_brain("expert"), DriveSettings(timing="lockstep", control_hz=CONTROL_HZ))
    finally:
        env.close()
    if trajectory.termination != "lap_completed":
        raise PilotlabError(f"the expert's perfect lap of {circuit} {direction} ended {trajectory.termination}; "
                            "BehaviorMetrics' metrics need one completed lap (is the circuit drivable?)")
    return perfect_lap_checkpoints(trajectory)
