"""Where BehaviorMetrics' worlds live: an assets folder laid out like JdeRobot's
RoboticsInfrastructure `CustomRobots/f1` (`worlds/<name>.world` + `models/<model>/...`).

The folder is named by `--assets DIR` on the CLI, the `worlds: {assets: DIR}` section of a recipe, or
`$PILOTLAB_BM_ASSETS`. A world is named by its `.world` file's stem (`simple_circuit`,
`simple_circuit_white_line`, ...). Nothing of BM's is shipped with pilotlab (third-party files).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

from matrix.errors import did_you_mean
from pilotlab.errors import PilotlabError

ASSETS_ENV = "PILOTLAB_BM_ASSETS"


def resolve_assets(assets: str | os.PathLike | None = None) -> Path:
    """The assets folder: `assets` if given, else $PILOTLAB_BM_ASSETS; checked to hold worlds/ and models/."""
    chosen = assets if assets not in (None, "") else os.environ.get(ASSETS_ENV)
    if not chosen:
        raise PilotlabError("no BehaviorMetrics assets folder: pass --assets DIR (a checkout of "
                            "RoboticsInfrastructure/CustomRobots/f1, with worlds/ and models/), set "
                            f"${ASSETS_ENV}, or set worlds.assets in the recipe")
    folder = Path(chosen).expanduser()
    if not folder.is_dir():   # it said "has no worlds/ folder" of a path that does not exist (outside test)
        what = "not a folder" if folder.exists() else "no such folder"
        raise PilotlabError(f"BehaviorMetrics assets folder {folder}: {what} (point at "
                            "RoboticsInfrastructure/CustomRobots/f1, with worlds/ and models/)")
    for part in ("worlds", "models"):
        if not (folder / part).is_dir():
            raise PilotlabError(f"{folder} is not a BehaviorMetrics assets folder: it has no {part}/ folder "
                                "(point at RoboticsInfrastructure/CustomRobots/f1)")
    return folder.resolve()


def world_names(assets: Path) -> list[str]:
    return sorted(path.stem for path in (assets / "worlds").glob("*.world"))


def world_path(assets: Path, name: str) -> Path:
    """The .world file of `name`; an unknown name lists the known ones."""
    path = assets / "worlds" / f"{name}.world"
    if name != Path(name).name or name in ("", ".", ".."):   # ../worlds/x would name a file outside worlds/
        raise PilotlabError(f"world {name!r}: a world is named by its .world file's stem in {assets / 'worlds'} "
                            f"(e.g. {Path(name).name or 'simple_circuit'}), not by a path")
    if not path.is_file():
        known = world_names(assets)
        raise PilotlabError(f"no world {name!r} in {assets / 'worlds'}{did_you_mean(name, known)}; "
                            f"it has: {', '.join(known) or 'none'}")
    return path


def content_digest(paths) -> str:
    """sha256 over the given files' names and bytes, in a fixed order: the world's cache key."""
    digest = hashlib.sha256()
    for path in sorted({Path(p) for p in paths}):
        digest.update(path.name.encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def world_assets(inputs) -> tuple[Path | None, str | None]:
    """(assets folder, world name) of a job from its `world` input (None, None: pilotlab's own world)."""
    path = inputs.get("world")
    if path is None:
        return None, None
    path = Path(path)
    return path.parent.parent, path.stem
