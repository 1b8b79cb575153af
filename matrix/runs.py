"""What a run is given and what it did, for both executors (the local process pool, matrix.execute;
Dask, matrix.dask_executor) and the commands: how many jobs run at once (`default_jobs`,
`worker_threads`) and one `Outcome` per job that did not start fresh, summed up in a `RunSummary`.
Nothing here starts processes, so the commands import it at their top and `plan` stays quick; the
executors are imported when a plan runs (matrix.engine.run_plan).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

# A job's status after a run: what its worker answered (matrix.worker), or what the executor decided.
OK, NOT_APPLICABLE, FAILED, BUSY, DONE_ELSEWHERE = "ok", "not_applicable", "failed", "busy", "done_elsewhere"
KEPT = "kept"   # its result stands: what it was made from ran again and came out the same
SKIPPED, NOT_STARTED = "skipped", "not_started"


@dataclass(frozen=True)
class Outcome:
    key: str
    name: str
    kind: str
    status: str          # ok | not_applicable | failed | skipped | not_started | done_elsewhere | kept
    reason: str = ""
    duration_s: float = 0.0


@dataclass
class RunSummary:
    outcomes: list[Outcome] = field(default_factory=list)
    fresh: int = 0
    wall_s: float = 0.0

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.status in (FAILED, SKIPPED, NOT_STARTED)]

    def counts(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for outcome in self.outcomes:
            counts[outcome.status] = counts.get(outcome.status, 0) + 1
        return counts


def cores() -> int:
    """Cores this process may run on (the affinity mask, not the machine's total)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def worker_share() -> int:
    """The cores this process may keep busy: its share when the engine runs jobs side by side
    (OMP_NUM_THREADS, set to cores // -j in each pool worker: matrix.worker.init_worker), else every core."""
    try:
        return max(1, int(os.environ["OMP_NUM_THREADS"]))
    except (KeyError, ValueError):
        return cores()


def default_jobs() -> int:
    """Jobs at once by default: one per core this process may use."""
    return cores()


def worker_threads(slots: int) -> int | None:
    """Threads each of `slots` workers' math libraries may use: the cores shared among them; None when
    one worker has every core: the libraries' own default then, as before (setting even the same count
    there changed a fine-tune's outcome: tests/pilotlab/online/test_own_network_lap.py)."""
    share = max(1, default_jobs() // max(1, slots))
    return share if share < default_jobs() else None
