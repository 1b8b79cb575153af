"""How a recipe names BehaviorMetrics' worlds, for the planner (pilotlab.planning): the `world` axis,
`datasets.NAME.record.worlds`, and the `worlds: {assets: DIR}` section.

A job in a world gets params `world` (the name) and `circuit` (the world's own circuit: a built-in name,
or the stem of the centreline CSV beside the .world file, which comes as input `circuit_csv`) and an input
`world`: its .world file, keyed by the digest of every file the world reads (SDF, meshes, textures,
centreline), so editing any of them reruns what drove there and nothing else, and moving them nothing.
"""
from __future__ import annotations

import os
from pathlib import Path

from matrix.errors import MatrixError
from matrix.jobs import InputFile, input_file
from pilotlab.worlds.assets import ASSETS_ENV


def assets_folder(planner, where: list) -> tuple[Path, str | None]:
    """The recipe's assets folder (relative to the recipe); where that is absent, $PILOTLAB_BM_ASSETS (so a
    shipped recipe runs wherever BM's worlds are), with the words an error about it then adds; with neither,
    an error naming both."""
    configured, from_env = planner.config.worlds.assets, os.environ.get(ASSETS_ENV)
    if configured is not None:
        if not (planner.folder / Path(configured).expanduser()).exists():
            if from_env:
                return Path(from_env), f"${ASSETS_ENV}, standing in for worlds.assets: {configured}, which does not exist"
            raise planner.recipe.error(f"{configured} does not exist (relative paths are relative to the recipe's "
                                       f"folder, {planner.folder}); point it at BM's worlds (a folder like "
                                       f"RoboticsInfrastructure/CustomRobots/f1), or set ${ASSETS_ENV}, which stands "
                                       "in where this folder is missing", ["worlds", "assets"])
        return planner.path(configured, ["worlds", "assets"]), None
    if from_env:
        return Path(from_env), f"${ASSETS_ENV}"
    raise planner.recipe.error(f"BehaviorMetrics' worlds are named here but the recipe has no `worlds: {{assets: "
                               f"DIR}}` (a folder like RoboticsInfrastructure/CustomRobots/f1) and ${ASSETS_ENV} "
                               "is not set", where)


def world_param(planner, name: str, where: list) -> tuple[dict, dict]:
    """(params, inputs) of a job in world `name`; the world is read once per plan."""
    cache = planner.worlds_read
    if name not in cache:
        from pilotlab.worlds.world import circuit_of, world_inputs
        assets, from_env = assets_folder(planner, where)
        try:
            path, parsed, digest = world_inputs(name, assets)
            circuit = circuit_of(name, path)
        except MatrixError as error:   # (an outside test's bad $PILOTLAB_BM_ASSETS was said without its source)
            said = f"{error} (the assets folder is {from_env})" if from_env else str(error)
            raise planner.recipe.error(said, where) from None
        inputs = {"world": InputFile(str(path), digest)}
        if circuit.endswith(".csv"):   # the world's own centreline: by its stem, read through an input (as
            inputs["circuit_csv"] = input_file(circuit)   # a recipe's CSV), so moving BM's assets reruns nothing
            circuit = Path(circuit).stem
        cache[name] = ({"world": name, "circuit": circuit}, inputs)
    return cache[name]
