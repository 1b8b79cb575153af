"""The circuit registry: the five JdeRobot follow-line circuits, plus user circuits from CSV files.

A circuit name is resolved in this order:
1. a built-in circuit (`pilotlab circuit list` shows them),
2. `NAME.csv` in a user circuit folder: each folder of `$PILOTLAB_CIRCUITS` (separated by `:`),
   then, for a recipe, `circuits/` beside the recipe file, then `./circuits/` in the working
   directory (where `pilotlab circuit import` saves by default),
3. a path to a CSV file of x, y points (`my_track.csv`, `data/laps/run3.csv`); in a recipe it is
   relative to the recipe's folder, as every path in a recipe.
A user CSV named like a built-in circuit is refused, not silently passed over (import refuses those names).

A CSV has one point per line, `x,y` in metres (comma or white space separated), in driving order;
an optional header line and `#` comment lines are skipped. It need not be closed exactly: a lap
that overruns its start is cut there, one that stops short is closed with a straight segment.

This module holds names and where to find them, so planning (which checks circuit names) imports no
numpy; the circuit itself is built by `pilotlab.circuits.load.get_circuit`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from matrix.errors import did_you_mean
from matrix.registry import Registry
from pilotlab.errors import PilotlabError

DEFAULT_ROAD_WIDTH_M = 6.0
USER_DIR_ENV = "PILOTLAB_CIRCUITS"
DEFAULT_USER_DIR = Path("circuits")


@dataclass(frozen=True)
class CircuitConfig:
    """A built-in circuit: its centreline CSV in pilotlab/circuits/data/ and how to build it."""
    name: str
    csv: str
    timeout_s: float                 # BehaviorMetrics' per-lap timeout (simulated seconds)
    road_width: float = DEFAULT_ROAD_WIDTH_M
    smoothing_m: float | None = None  # the centreline's Gaussian sigma; None: geometry.SMOOTHING_M
    version: int = 1


CIRCUITS: Registry[CircuitConfig] = Registry("circuit")

# Montreal was rasterised on a coarser grid (0.33 m instead of 0.13 m): it needs more smoothing.
for _name, _timeout, _smoothing in (("simple_circuit", 82.5, None), ("many_curves", 166.1, None),
                                    ("montmelo", 134.2, None), ("montreal", 272.8, 2.5), ("nurburgring", 96.8, None)):
    CIRCUITS.add(_name, CircuitConfig(_name, f"{_name}.csv", _timeout, smoothing_m=_smoothing))


def lap_scale(name: str) -> float:
    """How long a lap of built-in circuit `name` takes against one of simple_circuit (BehaviorMetrics'
    per-lap timeouts follow the circuits' lengths: Montreal's is 3.3 times simple_circuit's), for
    the scheduler's first guess; 1 for another circuit (its length is known once it is built)."""
    return CIRCUITS.get(name).timeout_s / CIRCUITS.get("simple_circuit").timeout_s if name in CIRCUITS else 1.0


def user_dirs(recipe_folder: Path | None = None) -> list[Path]:
    """Folders searched for `NAME.csv` user circuits, in order (`recipe_folder`: the recipe's, if any)."""
    listed = [Path(p) for p in os.environ.get(USER_DIR_ENV, "").split(os.pathsep) if p]
    beside_recipe = [recipe_folder / DEFAULT_USER_DIR] if recipe_folder is not None else []
    return listed + beside_recipe + [DEFAULT_USER_DIR]


def user_circuits(recipe_folder: Path | None = None) -> dict[str, Path]:
    """name -> CSV path of every user circuit found in the user folders (first folder wins)."""
    found: dict[str, Path] = {}
    for folder in user_dirs(recipe_folder):
        for csv in sorted(folder.glob("*.csv")) if folder.is_dir() else ():
            found.setdefault(csv.stem, csv)
    return found


def builtin_csv(config: CircuitConfig):
    return resources.files("pilotlab.circuits") / "data" / config.csv


def csv_path_of(name: str, recipe_folder: Path | None = None) -> Path | None:
    """The CSV a user circuit name or path refers to (None for a built-in circuit); a recipe's
    (`recipe_folder`) also finds circuits beside it, and its relative paths start there."""
    named = _user_csv(name, recipe_folder)   # a stat per folder: get_circuit asks at every episode
    if name in CIRCUITS:
        if named is not None and not _is_the_builtin(named, CIRCUITS.get(name)):
            raise PilotlabError(f"{named} has the name of a built-in circuit, which it does not replace; "
                                f"rename the file (e.g. my_{name}.csv) and use that name")
        return None
    if named is not None:
        return named
    if name.endswith(".csv") and (path := csv_file(name, recipe_folder)) is not None:
        return path
    known = CIRCUITS.names() + sorted(user_circuits(recipe_folder))
    relative = " (relative to the recipe's folder)" if recipe_folder is not None else ""
    raise PilotlabError(f"unknown circuit {name!r}{did_you_mean(name, known)}; known: {', '.join(known)}; "
                        f"or give the path of a CSV of x,y points{relative}, or put NAME.csv in one of: "
                        f"{', '.join(str(d) for d in user_dirs(recipe_folder))}")


def _is_the_builtin(path: Path, config: CircuitConfig) -> bool:
    """A user folder may hold the built-in's own file (BehaviorMetrics' centrelines, which pilotlab ships):
    that is no second circuit of the name (an outside test pointed PILOTLAB_CIRCUITS at them, and every
    built-in circuit was refused)."""
    try:
        return path.read_bytes().replace(b"\r\n", b"\n") == builtin_csv(config).read_bytes().replace(b"\r\n", b"\n")
    except OSError:
        return False


def _user_csv(name: str, recipe_folder: Path | None) -> Path | None:
    """NAME.csv in the first user folder that has it (as user_circuits, first folder wins)."""
    if not name or Path(name).name != name or name in (".", ".."):   # a path is not a user circuit's name
        return None
    try:
        return next((csv for folder in user_dirs(recipe_folder) if (csv := folder / f"{name}.csv").is_file()), None)
    except (OSError, ValueError):   # too long a name, a NUL byte: no such file
        return None


def csv_file(name: str, recipe_folder: Path | None) -> Path | None:
    """The CSV file a path names (relative to `recipe_folder` if given), or None if there is none."""
    try:
        path = Path(name).expanduser()
        path = path if path.is_absolute() or recipe_folder is None else recipe_folder / path
        return path if path.is_file() else None
    except (OSError, RuntimeError):   # too long a name, an unknown ~user
        return None


def all_circuit_names(recipe_folder: Path | None = None) -> list[str]:
    """Built-in circuits, then the user circuits found in the user folders."""
    return CIRCUITS.names() + [n for n in sorted(user_circuits(recipe_folder)) if n not in CIRCUITS]
