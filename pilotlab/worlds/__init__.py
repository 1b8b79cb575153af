"""BehaviorMetrics' own F1 worlds (Gazebo SDF + COLLADA) in pilotlab's simulator.

    from pilotlab.worlds import load_world
    world = load_world("simple_circuit", assets="path/to/RoboticsInfrastructure/CustomRobots/f1")

See docs/worlds.md. Modules: assets (where worlds are), sdf (the world and model files), collada
(meshes), scene (ground layers and solids), raster (top-down rasters), world (the cached, drivable
world), render (the fast camera renderer), bullet (the same world in pybullet), planning (the recipe's
world axis). The package itself imports nothing heavy: planning a recipe imports it without OpenCV.
"""
from __future__ import annotations

from pilotlab.worlds.assets import ASSETS_ENV, resolve_assets, world_names

__all__ = ["ASSETS_ENV", "BMWorld", "load_world", "resolve_assets", "world_names"]


def __getattr__(name: str):
    if name in ("BMWorld", "load_world"):      # world.py needs OpenCV: imported when asked for
        from pilotlab.worlds import world
        return getattr(world, name)
    raise AttributeError(f"module 'pilotlab.worlds' has no attribute {name!r}")
