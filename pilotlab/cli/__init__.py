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

import pydantic

from matrix.errors import MatrixError
from pilotlab.specs.base import spec_problem


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="pilotlab", description=__import__("pilotlab").__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="show tracebacks and debug logs")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):   # helpers, not commands
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (MatrixError, pydantic.ValidationError) as error:
        if args.verbose:
            traceback.print_exc()
        message = spec_problem(error) if isinstance(error, pydantic.ValidationError) else error
        print(f"pilotlab: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pilotlab: interrupted", file=sys.stderr)
        return 130
