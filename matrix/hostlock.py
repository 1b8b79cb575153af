"""One host, many runs: a job of an `exclusive` kind (a timing) has the host to itself, whichever
process runs it. The scheduler of one run keeps its own jobs apart; this lock keeps runs apart.

Every job holds this host's lock while it runs: shared for an ordinary job, exclusive for a timing
job. A waiting exclusive job goes first: it holds a turnstile that new shared holders pass through,
so a busy run with many short jobs cannot starve another run's timing job.

The lock is a file in the user's cache folder named after the host (`$MATRIX_HOST_LOCK` moves it),
so two runs on one host meet there even when their stores differ, and hosts sharing a home folder
over the network do not lock each other out. On Dask this is what keeps a timing job alone on its
host while the other hosts go on working (matrix.dask_executor).

A host is named by its host name, or by `$MATRIX_HOST` where one machine stands for several (two Dask
workers started with different names and lock files are two hosts to the engine: tests do so).
"""
from __future__ import annotations

import fcntl
import os
import socket
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path


def host_name() -> str:
    """This host's name: $MATRIX_HOST, else the host name."""
    return os.environ.get("MATRIX_HOST") or socket.gethostname() or "localhost"


def lock_path() -> Path:
    if os.environ.get("MATRIX_HOST_LOCK"):
        return Path(os.environ["MATRIX_HOST_LOCK"])
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return cache / "matrix" / f"host-{host_name()}.lock"


@contextmanager
def host_slot(exclusive: bool, waiting: Callable[[], None] | None = None,
              resumed: Callable[[], None] | None = None) -> Iterator[None]:
    """Hold the host's job lock (shared, or exclusive for a timing job) while the block runs; `waiting` is
    called first where another run holds it (so the job can say why it has not started), and `resumed`
    once it has the lock after such a wait."""
    with ExitStack() as stack:
        main, turnstile = _open(lock_path(), stack), _open(lock_path().with_suffix(".turnstile"), stack)
        if main is None or turnstile is None:
            yield                        # nowhere to keep a lock (a read-only home): run unguarded
            return
        told = _Told(waiting)
        _flock(turnstile, fcntl.LOCK_EX, told)
        try:
            _flock(main, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH, told)
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        if told.said and resumed is not None:
            resumed()
        try:
            yield
        finally:
            fcntl.flock(main, fcntl.LOCK_UN)


# Every holder passes the turnstile, so two jobs starting at the same instant meet there for a moment:
# a job says it waits only when the lock stays taken this long (it said so at every such meeting, and
# the word stayed on its progress line while it ran).
GRACE_S = 0.25


class _Told:
    """`waiting`, called at most once."""

    def __init__(self, waiting: Callable[[], None] | None):
        self.waiting, self.said = waiting, False

    def __call__(self) -> None:
        if not self.said and self.waiting is not None:
            self.said = True
            self.waiting()


def _flock(file, mode: int, waiting: _Told) -> None:
    deadline = time.monotonic() + GRACE_S
    while True:
        try:
            fcntl.flock(file, mode | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() >= deadline:
                break
            time.sleep(0.02)
    waiting()
    fcntl.flock(file, mode)


def _open(path: Path, stack: ExitStack):
    for candidate in (path, Path(tempfile.gettempdir()) / f"matrix-{os.getuid()}-{path.name}"):
        try:
            candidate.parent.mkdir(parents=True, exist_ok=True)
            return stack.enter_context(open(candidate, "a"))
        except OSError:
            continue
    return None
