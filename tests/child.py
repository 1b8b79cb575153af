"""The environment of a child interpreter that a test starts (a CLI run, a fresh process)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]   # the checkout under test


def python_path(*first: Path | str) -> str:
    """PYTHONPATH for the child: `first` (the checkout under test), then this process's own PYTHONPATH,
    which may be where the dependencies are (a host that installs nothing, as the GPU machine lent to a
    session: its carried packages sit in a folder named there)."""
    inherited = [os.path.abspath(entry) for entry in os.environ.get("PYTHONPATH", "").split(os.pathsep) if entry]
    return os.pathsep.join([*map(str, first), *inherited])


def run_pilotlab(*args: str, cwd: Path | str, timeout: float = 1200) -> subprocess.CompletedProcess:
    """`python -m pilotlab ARGS` in `cwd`, as a user runs it, importing this checkout's pilotlab."""
    env = {**os.environ, "PYTHONPATH": python_path(ROOT)}
    return subprocess.run([sys.executable, "-m", "pilotlab", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
