"""`--world NAME --assets DIR` for the commands that drive (`record`, `drive`): drive in one of
BehaviorMetrics' worlds (docs/worlds.md) instead of a circuit of pilotlab's own world."""
from __future__ import annotations

import argparse
from pathlib import Path

from pilotlab.errors import PilotlabError


def add_world_options(parser: argparse.ArgumentParser, place) -> None:
    """`place`: the mutually exclusive group that also holds --circuit."""
    place.add_argument("--world", help="a BehaviorMetrics world (pilotlab world list): drive there, with BM's camera")
    parser.add_argument("--assets", type=Path, default=None,
                        help="BehaviorMetrics' worlds folder (worlds/ + models/); default $PILOTLAB_BM_ASSETS")


def place_of(args: argparse.Namespace):
    """(spec values, assets, the world or None): where the command drives. A world is read (and
    converted, the first time) here, so a bad folder is one line before any progress bar."""
    if args.world is None:
        if args.assets is not None:
            raise PilotlabError("--assets names where BehaviorMetrics' worlds are: give --world too")
        return {"circuit": args.circuit}, None, None
    from pilotlab.worlds import load_world
    world = load_world(args.world, args.assets)
    return {"world": args.world, "circuit": world.meta["circuit"]}, args.assets, world
