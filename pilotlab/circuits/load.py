"""Building a circuit: its centreline CSV read (`read_points_csv`) and smoothed into a `Circuit`
(`get_circuit`), for a built-in name, a user circuit or a CSV path (how a name resolves:
pilotlab/circuits/registry.py, which names them without numpy).
"""
from __future__ import annotations

import functools
import re
from importlib import resources
from pathlib import Path

import numpy as np

from pilotlab.circuits.circuit import Circuit, check_direction
from pilotlab.circuits.geometry import SMOOTHING_M
from pilotlab.circuits.registry import CIRCUITS, DEFAULT_ROAD_WIDTH_M, builtin_csv, csv_path_of
from pilotlab.errors import PilotlabError

MAX_COORDINATE_M = 1e6          # 1000 km: a circuit CSV in metres is far inside; 1e12 is a unit error


def read_points_csv(path: Path) -> np.ndarray:
    """The x, y points of a CSV file (the format: pilotlab/circuits/registry.py)."""
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
    rows, first = [], True
    for number, line in enumerate(text.splitlines(), start=1):
        fields = [f for f in re.split(r"[,\s;]+", line.split("#")[0].strip()) if f]
        if not fields:
            continue
        try:
            rows.append(_point(fields, path, number))
        except (ValueError, IndexError):
            if not first:  # only the first line may be a header (a one-column file was read as all headers)
                raise PilotlabError(f"{path}:{number}: expected 'x,y' in metres, got {line.strip()[:80]!r}") from None
        first = False
    if len(rows) < 3:
        raise PilotlabError(f"{path}: a circuit CSV needs at least 3 'x,y' lines, found {len(rows)}")
    return np.array(rows, dtype=np.float64)


def _point(fields: list[str], path: Path, number: int) -> tuple[float, float]:
    x, y = float(fields[0]), float(fields[1])
    if not (abs(x) <= MAX_COORDINATE_M and abs(y) <= MAX_COORDINATE_M):   # also false for NaN
        raise PilotlabError(f"{path}:{number}: the point ({fields[0][:20]}, {fields[1][:20]}) is not a finite "
                            f"coordinate within {MAX_COORDINATE_M:g} m of the origin; coordinates are metres")
    return x, y


@functools.lru_cache(maxsize=16)
def _builtin(name: str) -> Circuit:
    config = CIRCUITS.get(name)
    with resources.as_file(builtin_csv(config)) as csv:
        raw = read_points_csv(csv)
    return Circuit.from_points(name, raw, road_width=config.road_width, timeout_s=config.timeout_s,
                               source=f"pilotlab/circuits/data/{config.csv}",
                               smoothing=SMOOTHING_M if config.smoothing_m is None else config.smoothing_m)


@functools.lru_cache(maxsize=16)
def _from_csv(path: Path, mtime: float, road_width: float) -> Circuit:
    return Circuit.from_points(path.stem, read_points_csv(path), road_width=road_width, source=str(path))


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
