"""The environment of a child interpreter that a test starts (a CLI run, a fresh process)."""
from __future__ import annotations

import os
from pathlib import Path


def python_path(*first: Path | str) -> str:
    """PYTHONPATH for the child: `first` (the checkout under test), then this process's own PYTHONPATH,
    which may be where the dependencies are (a host that installs nothing, as the GPU machine lent to a
    session: its carried packages sit in a folder named there)."""
    inherited = [os.path.abspath(entry) for entry in os.environ.get("PYTHONPATH", "").split(os.pathsep) if entry]
    return os.pathsep.join([*map(str, first), *inherited])
