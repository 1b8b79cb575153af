"""One root exception for everything the engine (and the domain on top of it) raises on purpose.

The CLI catches `MatrixError`, prints its one-line message and exits non-zero; anything else is a bug
and gets a traceback.
"""
from __future__ import annotations

import difflib
import re
import traceback
from collections.abc import Iterable


class MatrixError(Exception):
    """Root of every error a user can cause: bad recipe, bad input file, failed job, unknown name."""


class Terminated(KeyboardInterrupt):
    """The run was asked to stop by SIGTERM (`kill PID`, `timeout`, a batch system): it stops as at Ctrl-C,
    the jobs in flight lost, nothing half-written."""


def full_traceback(error: BaseException) -> str:
    """`error`'s traceback with the exceptions it was raised from or while handling, even those a
    `raise ... from None` left out for the sake of a one-line message (what `-v` and `show` print: where
    the error came from in a user's code, a brain's or a network's, was cut from it)."""
    seen, chained = set(), error
    while chained is not None and id(chained) not in seen:
        seen.add(id(chained))
        chained.__suppress_context__ = False
        chained = chained.__cause__ or chained.__context__
    return "".join(traceback.format_exception(error))


def exit_message(exit_: SystemExit) -> str:
    """What to say when code run for a job or command (a user's network module, a brain) called
    sys.exit(): left alone, it would end the whole run with its code and no word."""
    return (f"code of yours called exit({exit_.code!r}) while it ran (SystemExit); raise an exception instead "
            "(a module that exits when imported, or parses the command line, cannot be loaded either)")


_LONG_TOKEN = re.compile(r"\S{240,}")   # a value quoted whole would drown the message


class RecipeError(MatrixError):
    """A recipe is malformed. The message starts with `file:line: key.path:` (`file:line:column:` where
    the column is known)."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 path: Iterable[object] = (), column: int | None = None):
        message = _LONG_TOKEN.sub(lambda m: f"{m[0][:60]}...{m[0][-20:]} ({len(m[0])} characters)", message)
        self.message, self.file, self.line, self.path, self.column = message, file, line, tuple(path), column
        where = ":".join(str(p) for p in (file, line, column if line is not None else None) if p is not None)
        key = ".".join(str(p) if len(str(p)) <= 60 else str(p)[:50] + "..." for p in self.path)
        prefix = ": ".join(p for p in (where, key) if p)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class CycleError(MatrixError):
    """The job graph has a cycle; `path` lists the jobs on it, first == last."""

    def __init__(self, path: list[str]):
        self.path = path
        super().__init__("dependency cycle: " + " -> ".join(path))


class UnknownNameError(MatrixError):
    """A name is not in a registry; the message lists the known names and the closest one."""

    def __init__(self, what: str, name: str, known: Iterable[str]):
        known = sorted(known)
        self.name, self.known = name, known
        super().__init__(f"unknown {what} {name!r}{did_you_mean(name, known)}; known: {', '.join(known) or '(none)'}")


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the closest known name, or '' when nothing is close. A known name
    that begins as the given one does (4 characters or more: 'colour' for 'color_jitter') is closer
    than one that only shares letters ('blur')."""
    name, known = str(name), [str(k) for k in known]
    start = name.lower()[:4] if len(name) >= 4 else None
    prefixed = [k for k in known if k.lower()[:4] == start]
    close = difflib.get_close_matches(name, prefixed, n=1, cutoff=0.0) or \
        difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def shown(value: object, limit: int = 80) -> str:
    """repr(value), cut to about `limit` characters: an error message quotes what it was given, not
    the 5,000 characters of it."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 10]}...{text[-6:]} ({len(text)} characters)"
