"""`pilotlab run | plan | status | show | gc`: the engine's commands on the driving domain."""
from __future__ import annotations

from matrix.cli import add_engine_commands


def _domain():
    from pilotlab.domain import DOMAIN  # imported when a command runs, so `--help` stays quick
    return DOMAIN


def register(subparsers) -> None:
    add_engine_commands(subparsers, _domain,
                        store_help="job store folder (default: $PILOTLAB_STORE, else .pilotlab)")
