"""The `pilotlab` command line.

Each module in this package adds its own sub-commands: it defines `register(subparsers)` and sets
`func=` on the parsers it adds. `func(args)` returns the exit status. Errors the user can fix
(`MatrixError`) print one line and exit non-zero; `--verbose` adds the traceback.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import signal
import sys
import traceback

import pydantic

from matrix.errors import MatrixError, Terminated, exit_message, full_traceback
from pilotlab.specs.base import spec_problem


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser; given the arguments, only the module of the command they name is imported (its
    options come from spec models that other commands do not need), else every command's."""
    parser = argparse.ArgumentParser(prog="pilotlab", description=__import__("pilotlab").__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="show tracebacks and debug logs")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in _command_modules(argv):
        importlib.import_module(f"{__name__}.{name}").register(subparsers)
    _verbose_anywhere(parser)
    return parser


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """A parser's sub-commands by name (argparse keeps them in its one sub-parsers action)."""
    return parser._subparsers._group_actions[0].choices if parser._subparsers else {}


def _command_parser(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.ArgumentParser:
    """The parser of the (sub-)command `argv` names."""
    for token in argv:
        parser = _commands(parser).get(token, parser)
    return parser


def _verbose_anywhere(parser: argparse.ArgumentParser) -> None:
    """-v after the command too (`pilotlab plan R -v`), on every command and sub-command: not given there, it
    leaves the one before the command as it was."""
    for command in {id(p): p for p in _commands(parser).values()}.values():   # aliases: one parser
        if "--verbose" not in command._option_string_actions:
            command.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                                 help="show tracebacks and debug logs")
        _verbose_anywhere(command)


def _command_modules(argv: list[str] | None) -> list[str]:
    """The modules that define commands: a module is named like its command, but for the engine's."""
    from matrix.cli import ENGINE_COMMANDS
    modules = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))  # _helpers
    command = next((arg for arg in argv or () if not arg.startswith("-")), None)
    owner = "engine" if command in ENGINE_COMMANDS else command
    return [owner] if owner in modules else modules


def os_problem(error: OSError) -> str:
    """One line for a file-system error on a path the user gave (or one made from it)."""
    where = f"{error.filename} -> {error.filename2}" if error.filename2 else str(error.filename)
    return (f"{where}: {error.strerror or error} ({type(error).__name__}); give a path where pilotlab can "
            "make folders and write files")


def _stopped(args: argparse.Namespace) -> str:
    """What a stopped `run` leaves (Ctrl-C said only "interrupted", SIGTERM this: outside test)."""
    if args.command != "run":
        return ""
    on_dask = getattr(args, "executor", "local") == "dask"   # dask-local's cluster closes with the run
    return ": the jobs that finished are kept" + (
        "; the jobs already running on the Dask workers run to their end there (Dask cannot stop a running task), "
        "and their results are kept too" if on_dask else "") + "; run again to go on"


def main(argv: list[str] | None = None) -> int:
    if argv is None:   # the program itself (not a caller's main([...])): `pilotlab plan R | head` ends quietly,
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)   # as Unix tools do, when head stops reading
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv)
    args, unknown = parser.parse_known_args(argv)
    if unknown:   # said by the command's own parser, with its usage (argparse's top-level one showed pilotlab's)
        _command_parser(parser, argv).error(f"unrecognized arguments: {' '.join(unknown)}")
    try:
        return int(args.func(args) or 0)
    except (MatrixError, pydantic.ValidationError) as error:
        if args.verbose:   # with what it was raised from: a user's brain or network, whose frames a one-line
            print(full_traceback(error), end="", file=sys.stderr)   # message leaves out
        message = spec_problem(error) if isinstance(error, pydantic.ValidationError) else error
        print(f"pilotlab: error: {message}", file=sys.stderr)
        return 2
    except OSError as error:        # a path given that cannot be made or written: a file where a folder goes...
        if error.filename is None:   # no path of the user's in it: a bug, with its traceback
            raise
        if args.verbose:
            traceback.print_exc()
        print(f"pilotlab: error: {os_problem(error)}", file=sys.stderr)
        return 2
    except SystemExit as exit_:     # argparse's exits happen above; here it is code of the user's (a brain)
        if args.verbose:
            traceback.print_exc()
        from pilotlab.usercode import error_place
        place = error_place(exit_)   # where (a brain's act): the message said nothing of it (outside test)
        print(f"pilotlab: error: {f'{place}: ' if place else ''}{exit_message(exit_)}", file=sys.stderr)
        return 2
    except Terminated:
        print(f"pilotlab: terminated (SIGTERM){_stopped(args)}", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"pilotlab: interrupted{_stopped(args)}", file=sys.stderr)
        return 130
