"""A circuit named by a path that names no file: said as such (where it was looked for), before the
registry's "unknown circuit" (which lists names, and would tell a user who gave a path to give one).
Apart from the registry, which every job's code holds: a message here changes no job key."""
from __future__ import annotations

from pathlib import Path

from pilotlab.circuits.registry import CIRCUITS, csv_file


def names_a_path(name: str) -> bool:
    return name not in CIRCUITS and (name.endswith(".csv") or "/" in name)


def missing_csv(name: str, folder: Path | None = None) -> str | None:
    """Why circuit `name` (relative to `folder`, a recipe's) names no CSV, when it is a path; None otherwise."""
    if not names_a_path(name) or csv_file(name, folder) is not None:
        return None
    try:
        looked = Path(name).expanduser()
        looked = (looked if looked.is_absolute() or folder is None else folder / looked).resolve()
    except (OSError, RuntimeError, ValueError):
        looked = Path(name)
    relative = " (relative paths start at the recipe's folder)" if folder is not None else ""
    return (f"circuit {name!r}: no such CSV file (looked for {looked}){relative}; give the path of a CSV of x,y "
            "points of a closed centreline, or a circuit's name (`pilotlab circuit list`)")


def load_named(name: str, direction: str = "cw"):
    """The circuit the command line names (pilotlab.circuits.load.get_circuit), a missing CSV said as such."""
    from pilotlab.circuits.load import get_circuit
    from pilotlab.errors import PilotlabError
    if problem := missing_csv(name):
        raise PilotlabError(problem)
    return get_circuit(name, direction)
