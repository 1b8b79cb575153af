"""The circuit registry: the five JdeRobot follow-line circuits, plus user circuits from CSV files.

A circuit name is resolved in this order:
1. a built-in circuit (`pilotlab circuit list` shows them),
2. `NAME.csv` in a user circuit folder: each folder of `$PILOTLAB_CIRCUITS` (separated by `:`),
   then `./circuits/` in the working directory (where `pilotlab circuit import` saves by default),
3. a path to a CSV file of x, y points (`my_track.csv`, `data/laps/run3.csv`).

A CSV has one point per line, `x,y` in metres (comma or white space separated), in driving order;
an optional header line and `#` comment lines are skipped. It need not be closed exactly: a lap
that overruns its start is cut there, one that stops short is closed with a straight segment.
"""
from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from matrix.errors import did_you_mean
from matrix.registry import Registry
from pilotlab.circuits.circuit import Circuit, check_direction
from pilotlab.circuits.geometry import SMOOTHING_M
from pilotlab.errors import PilotlabError

DEFAULT_ROAD_WIDTH_M = 6.0
MAX_COORDINATE_M = 1e6          # 1000 km: a circuit CSV in metres is far inside; 1e12 is a unit error
USER_DIR_ENV = "PILOTLAB_CIRCUITS"
DEFAULT_USER_DIR = Path("circuits")


@dataclass(frozen=True)
class CircuitConfig:
    """A built-in circuit: its centreline CSV in pilotlab/circuits/data/ and how to build it."""
    name: str
    csv: str
    timeout_s: float                 # BehaviorMetrics' per-lap timeout (simulated seconds)
    road_width: float = DEFAULT_ROAD_WIDTH_M
    smoothing_m: float = SMOOTHING_M
    version: int = 1


CIRCUITS: Registry[CircuitConfig] = Registry("circuit")

# Montreal was rasterised on a coarser grid (0.33 m instead of 0.13 m): it needs more smoothing.
for _name, _timeout, _smoothing in (("simple_circuit", 82.5, SMOOTHING_M), ("many_curves", 166.1, SMOOTHING_M),
                                    ("montmelo", 134.2, SMOOTHING_M), ("montreal", 272.8, 2.5),
                                    ("nurburgring", 96.8, SMOOTHING_M)):
    CIRCUITS.add(_name, CircuitConfig(_name, f"{_name}.csv", _timeout, smoothing_m=_smoothing))


def read_points_csv(path: Path) -> np.ndarray:
    """The x, y points of a CSV file (see the module docstring for the format)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as error:
        raise PilotlabError(f"{path}: cannot read circuit CSV ({error.strerror})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise PilotlabError(f"{path}:{line}: not a text file (byte {data[error.start]:#04x} is not UTF-8); "
                            "a circuit CSV has one 'x,y' line per point") from None
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = [f for f in re.split(r"[,\s;]+", line.split("#")[0].strip()) if f]
        if not fields:
            continue
        try:
            rows.append(_point(fields, path, number))
        except (ValueError, IndexError):
            if rows:  # only a first line may be a header
                raise PilotlabError(f"{path}:{number}: expected 'x,y' in metres, got {line.strip()[:80]!r}") from None
    if len(rows) < 3:
        raise PilotlabError(f"{path}: a circuit CSV needs at least 3 'x,y' lines, found {len(rows)}")
    return np.array(rows, dtype=np.float64)


def _point(fields: list[str], path: Path, number: int) -> tuple[float, float]:
    x, y = float(fields[0]), float(fields[1])
    if not (abs(x) <= MAX_COORDINATE_M and abs(y) <= MAX_COORDINATE_M):   # also false for NaN
        raise PilotlabError(f"{path}:{number}: the point ({fields[0][:20]}, {fields[1][:20]}) is not a finite "
                            f"coordinate within {MAX_COORDINATE_M:g} m of the origin; coordinates are metres")
    return x, y


def user_dirs() -> list[Path]:
    """Folders searched for `NAME.csv` user circuits, in order."""
    listed = [Path(p) for p in os.environ.get(USER_DIR_ENV, "").split(os.pathsep) if p]
    return listed + [DEFAULT_USER_DIR]


def user_circuits() -> dict[str, Path]:
    """name -> CSV path of every user circuit found in the user folders (first folder wins)."""
    found: dict[str, Path] = {}
    for folder in user_dirs():
        for csv in sorted(folder.glob("*.csv")) if folder.is_dir() else ():
            found.setdefault(csv.stem, csv)
    return found


def builtin_csv(config: CircuitConfig):
    return resources.files("pilotlab.circuits") / "data" / config.csv


@functools.lru_cache(maxsize=16)
def _builtin(name: str) -> Circuit:
    config = CIRCUITS.get(name)
    with resources.as_file(builtin_csv(config)) as csv:
        raw = read_points_csv(csv)
    return Circuit.from_points(name, raw, road_width=config.road_width, timeout_s=config.timeout_s,
                               source=f"pilotlab/circuits/data/{config.csv}", smoothing=config.smoothing_m)


@functools.lru_cache(maxsize=16)
def _from_csv(path: Path, mtime: float, road_width: float) -> Circuit:
    return Circuit.from_points(path.stem, read_points_csv(path), road_width=road_width, source=str(path))


def csv_path_of(name: str) -> Path | None:
    """The CSV a user circuit name or path refers to (None for a built-in circuit)."""
    if name in CIRCUITS:
        return None
    if name in (found := user_circuits()):
        return found[name]
    if name.endswith(".csv") and Path(name).is_file():
        return Path(name)
    known = CIRCUITS.names() + sorted(found)
    raise PilotlabError(f"unknown circuit {name!r}{did_you_mean(name, known)}; known: {', '.join(known)}; "
                        f"or give the path of a CSV of x,y points, or put NAME.csv in one of: "
                        f"{', '.join(str(d) for d in user_dirs())}")


def get_circuit(name: str, direction: str = "cw", road_width: float | None = None) -> Circuit:
    """The circuit called `name` (built-in, user folder, or CSV path), driven in `direction`."""
    check_direction(direction)
    path = csv_path_of(name)
    if path is None:
        circuit = _builtin(name)
        if road_width is not None and road_width != circuit.road_width:
            circuit = Circuit(name, circuit.points, road_width=road_width, timeout_s=circuit.timeout_s,
                              source=circuit.source)
    else:
        resolved = path.resolve()
        circuit = _from_csv(resolved, resolved.stat().st_mtime, road_width or DEFAULT_ROAD_WIDTH_M)
    return circuit.directed(direction)


def all_circuit_names() -> list[str]:
    """Built-in circuits, then the user circuits found in the user folders."""
    return CIRCUITS.names() + [n for n in sorted(user_circuits()) if n not in CIRCUITS]
