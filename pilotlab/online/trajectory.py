"""The record of one closed-loop run: what the metrics are computed from.

A `Trajectory` holds one sample per brain iteration — the car's state when the brain's camera image
was taken and the command the brain decided from it — plus one last sample where the run ended (its
command columns are NaN: no decision was made there). Times are simulated seconds since the start
(`t`) and wall-clock seconds since the start (`wall`). Positions are metres in the world frame;
`progress` is metres driven along the red line in the driving direction since the start (it exceeds
the circuit length after a lap); `lateral` is the signed distance from the red line (+ left).

Per decision: `brain_s` is the wall-clock time of the whole brain iteration (camera image in,
command out: preprocessing, inference, de-normalisation, and any artificial latency); `inference_s`
the time of the decision itself (the network's predict call, or the reference brain's computation),
plus any artificial latency; `charged_s` the simulated time the timing mode charged before the
command reached the car (0 in lockstep).

Saved as `.npz` (arrays, lossless) and `.csv` (one row per sample, a `run` column when several runs
share a file).
"""
from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pilotlab.errors import PilotlabError

COLUMNS = ("t", "wall", "x", "y", "yaw", "speed", "progress", "lateral", "off_road", "v", "w",
           "brain_s", "inference_s", "charged_s")


@dataclass
class Trajectory:
    t: np.ndarray            # simulated seconds since the start
    wall: np.ndarray         # wall-clock seconds since the start
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    speed: np.ndarray        # forward speed, m/s
    progress: np.ndarray     # metres along the red line since the start
    lateral: np.ndarray      # signed distance from the red line, metres
    off_road: np.ndarray     # bool: the car's centre is off the road
    v: np.ndarray            # command decided at this sample (NaN on the last sample)
    w: np.ndarray
    brain_s: np.ndarray
    inference_s: np.ndarray
    charged_s: np.ndarray
    circuit_length: float
    meta: dict[str, Any] = field(default_factory=dict)   # circuit, direction, start_m, termination, ...

    def __post_init__(self):
        for name in COLUMNS:
            setattr(self, name, np.asarray(getattr(self, name), dtype=bool if name == "off_road" else np.float64))
        lengths = {name: len(getattr(self, name)) for name in COLUMNS}
        if len(set(lengths.values())) != 1 or not lengths["t"]:
            raise PilotlabError(f"a trajectory needs columns of one non-zero length, got {lengths}")
        if self.circuit_length <= 0:
            raise PilotlabError(f"a trajectory's circuit length must be positive, got {self.circuit_length}")

    def __len__(self) -> int:
        return len(self.t)

    @property
    def decisions(self) -> np.ndarray:
        """Index of the samples where the brain decided a command."""
        return np.flatnonzero(np.isfinite(self.v))

    @property
    def termination(self) -> str | None:
        return self.meta.get("termination")

    def columns(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name in COLUMNS}


class TrajectoryBuilder:
    """Collects samples during a run; `build()` makes the Trajectory."""

    def __init__(self, circuit_length: float, meta: dict[str, Any] | None = None):
        self.circuit_length, self.meta = circuit_length, dict(meta or {})
        self.rows: list[tuple] = []

    def sample(self, info: dict[str, Any], wall: float) -> None:
        """The car's state now (from the env's info dict), with no decision yet."""
        x, y, yaw = info["pose"]
        self.rows.append((info["sim_time"], wall, x, y, yaw, info["speed"], info["progress"],
                          info["lateral_offset"], info["off_road"]) + (np.nan,) * 5)

    def decide(self, command, brain_s: float, inference_s: float, charged_s: float) -> None:
        """Attach the brain's decision to the latest sample."""
        self.rows[-1] = self.rows[-1][:-5] + (command[0], command[1], brain_s, inference_s, charged_s)

    def build(self, **meta: Any) -> Trajectory:
        columns = list(zip(*self.rows))
        return Trajectory(*columns, circuit_length=self.circuit_length, meta={**self.meta, **meta})


def save_npz(trajectories: list[Trajectory], path: Path) -> Path:
    """All runs in one .npz: `run{i}.{column}` arrays and `run{i}.meta` (JSON text)."""
    arrays = {}
    for i, trajectory in enumerate(trajectories):
        arrays.update({f"run{i}.{name}": values for name, values in trajectory.columns().items()})
        meta = {**trajectory.meta, "circuit_length": trajectory.circuit_length}
        arrays[f"run{i}.meta"] = np.array(json.dumps(meta))
    np.savez_compressed(path, **arrays)
    return Path(path)


def load_npz(path: Path) -> list[Trajectory]:
    with np.load(path) as data:
        runs = sorted({key.split(".")[0] for key in data.files}, key=lambda r: int(r[3:]))
        loaded = []
        for run in runs:
            meta = json.loads(str(data[f"{run}.meta"]))
            length = meta.pop("circuit_length")
            loaded.append(Trajectory(**{name: data[f"{run}.{name}"] for name in COLUMNS},
                                     circuit_length=length, meta=meta))
    return loaded


def save_csv(trajectories: list[Trajectory], path: Path) -> Path:
    """One tidy row per sample: run, then the columns (empty where a value is NaN)."""
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(("run",) + COLUMNS)
        for i, trajectory in enumerate(trajectories):
            for row in zip(*trajectory.columns().values()):
                writer.writerow((i,) + tuple(_cell(value) for value in row))
    return Path(path)


def _cell(value) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    return "" if not np.isfinite(value) else f"{float(value):.6g}"

