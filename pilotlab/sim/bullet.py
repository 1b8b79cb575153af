"""pybullet, imported without the "pybullet build time: …" line its C module writes to stderr,
which every command that loads the simulator would otherwise print.

    from pilotlab.sim.bullet import p
"""
from __future__ import annotations

import os
import sys


def _quiet_import():
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    return pybullet


p = _quiet_import()
