"""The `pilotlab` command line.

Each module in this package adds its own sub-commands: it defines `register(subparsers)` and sets
`func=` on the parsers it adds. `func(args)` returns the exit status. Errors the user can fix
(`MatrixError`) print one line and exit non-zero; `--verbose` adds the traceback.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import traceback

from matrix.errors import MatrixError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="pilotlab", description=__import__("pilotlab").__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="show tracebacks and debug logs")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except MatrixError as error:
        if args.verbose:
            traceback.print_exc()
        print(f"pilotlab: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pilotlab: interrupted", file=sys.stderr)
        return 130
