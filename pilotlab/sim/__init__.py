"""The driving simulator: a pybullet world with the circuit's road, a car, its camera, drivers, recording.

Start with `pilotlab.sim.env.DrivingEnv` (docs/simulator.md has the tour). Importing this package
registers the environment with Gymnasium as `pilotlab/FollowLine-v0` (docs/simulator-python.md).

Planning imports this package (to fingerprint the simulator's modules) and must stay quick, so
gymnasium (~60 ms) is not imported here: the registration happens now if gymnasium is already
imported, else the moment it is.
"""
from __future__ import annotations

import importlib.abc
import importlib.util
import sys


def _register() -> None:
    from pilotlab.sim.follow_line import register
    register()


class _RegisterOnImport(importlib.abc.MetaPathFinder):
    """Finds gymnasium as the other finders do, and registers the environment once it has loaded."""
    _finding = False

    def find_spec(self, name, path, target=None):
        if name != "gymnasium" or self._finding:
            return None
        self._finding = True   # the search below asks every finder, this one too
        try:
            spec = importlib.util.find_spec(name)
        finally:
            self._finding = False
        if spec is None or spec.loader is None:
            return spec
        load = spec.loader.exec_module

        def exec_module(module):
            load(module)
            if self in sys.meta_path:
                sys.meta_path.remove(self)
            _register()
        spec.loader.exec_module = exec_module
        return spec


if "gymnasium" in sys.modules:
    _register()
elif not any(isinstance(finder, _RegisterOnImport) for finder in sys.meta_path):
    sys.meta_path.insert(0, _RegisterOnImport())
