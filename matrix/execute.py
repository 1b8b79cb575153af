"""Running the stale part of a plan on a local process pool.

The driver keeps the schedule (which jobs are ready, which are blocked by a failure); workers run
`matrix.worker.execute_job`, which does the locking and the atomic commit. Jobs of an `exclusive`
kind (timings) run alone: one waits until the running jobs are done, and nothing starts beside it
(`Schedule.take`), so its figures come from a quiet host whatever `-j` is. A failed job's dependents are skipped; without `keep_going` nothing new
starts after the first failure.
"""
from __future__ import annotations

import heapq
import math
import multiprocessing
import os
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from matrix.dag import critical_paths, dependents
from matrix.display import Display, NullDisplay
from matrix.errors import Terminated
from matrix.jobs import Job
from matrix.kinds import KINDS
from matrix.runs import BUSY, DONE_ELSEWHERE, FAILED, NOT_STARTED, SKIPPED, Outcome, RunSummary, worker_threads
from matrix.stale import FRESH, JobStatus, results_to_replace
from matrix.store import Store
from matrix.times import KindStats
from matrix.worker import execute_job, init_worker

BUSY_RETRY_S = 0.2
BACKFILL_SCAN = 256   # the best-ranked waiting jobs looked at for one that fits before an exclusive job
OVERRUN_SHARE = 0.25   # of its time so far, what a job past its estimate is expected to run on


class Schedule:
    """Which stale jobs may start: all their stale dependencies done, none failed.

    Ready jobs start in order of their critical path (`matrix.dag.critical_paths`: a job's expected
    seconds plus those of the longest chain of jobs waiting on it), then in plan order, so the
    critical path moves first: a training that the whole study waits on starts before a reference lap
    that only the report needs. `expected(job)` gives seconds (`matrix.times.KindStats`); without it
    every job counts 1 and the longest chain in jobs decides.

    A job that runs alone (a timing) waits for the running jobs to finish; meanwhile a job it outranks
    starts only if it is expected to end before they are (backfilling, as batch schedulers do): the
    idle core works and the timing starts no later for it. The same holds from the moment every
    dependency it still waits for is running, where those end soon against what would start instead:
    the study's training, which runs alone, waited 75 s for a reference lap that had started on the
    core its next-to-last recording freed a second before the last one."""

    def __init__(self, stale: list[Job], expected: Callable[[Job], float] | None = None):
        self.jobs = {job.key: job for job in stale}
        # one entry per dependency, even one a job needs under two roles (else it would be made ready twice)
        self.graph = {job.key: list(dict.fromkeys(d.key for d in job.dep_jobs() if d.key in self.jobs))
                      for job in stale}
        self.waiting = {key: set(deps) for key, deps in self.graph.items()}
        self.needed_by: dict[str, list[str]] = {}
        for key, deps in self.graph.items():
            for dep in deps:
                self.needed_by.setdefault(dep, []).append(key)
        self.estimated = expected is not None   # without estimates nothing is backfilled (no time to fit in)
        self.expected = {key: _seconds(expected(job)) if expected else 1.0 for key, job in self.jobs.items()}
        path = critical_paths(self.graph, self.expected.__getitem__)
        self.rank = {key: (-path[key], order) for order, key in enumerate(self.jobs)}
        self.alone_keys = {key for key, job in self.jobs.items() if runs_alone(job)}
        self.alone: list[tuple] = []    # heaps of (rank, key): jobs that run alone, and the others
        self.beside: list[tuple] = []
        self.coming: list[tuple] = []   # jobs that run alone, not ready, whose missing dependencies all run
        for key in self.jobs:
            if not self.waiting[key]:
                self._make_ready(key)
        self.later: list[tuple[float, str]] = []   # jobs another run holds, retried after a pause
        self.settled: set[str] = set()
        self.started: dict[str, float] = {}        # running jobs: when they started (monotonic)

    def has_work(self) -> bool:
        return bool(self.alone or self.beside or self.later)

    def take(self, exclusive_running: bool, running: int, slots: int) -> Job | None:
        self._wake()
        if exclusive_running or running >= slots or not self.has_ready():
            return None
        if not running:  # an idle host: the first job, exclusive or not
            return self._starting(self.next_ready())
        # Others run: an exclusive job waits until the host is idle (it then runs alone). Work of its
        # rank or lower goes on meanwhile; work it outranks waits with it, so that a training many
        # jobs need is not held up behind a long job nothing needs, unless it fits before the host is idle.
        if self.beside and not self._exclusive_outranks_the_rest():
            return self._starting(self.jobs[heapq.heappop(self.beside)[1]])
        return self._starting(self._backfill()) if self.beside and self.estimated else None

    def _exclusive_outranks_the_rest(self) -> bool:
        """The first exclusive job, ready or coming, has a longer chain waiting on it than the first of
        the others."""
        negated_path = 0   # a heap entry is (rank, key), rank = (-critical path, plan order)
        heads = [self.alone[0]] if self.alone else []
        if (coming := self._coming_head()) is not None and self._worth_holding_for_coming():
            heads.append(coming)
        return bool(heads) and min(heads)[0][negated_path] < self.beside[0][0][negated_path]

    def _worth_holding_for_coming(self) -> bool:
        """Whether a free core is better kept for a job not ready yet than given to the first other one:
        while the running jobs end sooner than that job would hold it up past them (the study's training,
        due in a second, against a 76 s lap); not while a fine-tune has a minute to go (the lap starts,
        and the timing after the fine-tune waits less than the core would have idled)."""
        window = self._running_window()
        return window < self.expected[self.beside[0][1]] - window

    def _running_window(self) -> float:
        """Seconds until the running jobs are all expected to have ended. A job past its estimate is
        expected to run OVERRUN_SHARE of its time so far again: its guess was short by an unknown factor,
        and counting it as ending now left a core idle (the study's CQAT fine-tune, guessed 15 s, ran 31;
        a timing waited the last 15 s of it with one core idle and a dozen 1-3 s conversions ready)."""
        now = time.monotonic()
        left = (max(at + self.expected[key] - now, OVERRUN_SHARE * (now - at)) for key, at in self.started.items())
        return max(left, default=0.0)

    def _coming_head(self) -> tuple | None:
        """The first-ranked job that runs alone and will be ready once the running jobs end (entries
        that no longer are, become ready, blocked or waiting on a job put back, are dropped here)."""
        while self.coming:
            key = self.coming[0][1]
            if key not in self.settled and self.waiting[key] and self.waiting[key] <= self.started.keys():
                return self.coming[0]
            heapq.heappop(self.coming)
        return None

    def _backfill(self) -> Job | None:
        """The first-ranked waiting job expected to end before the running ones are (so the exclusive
        job starts no later); None when none is."""
        window = self._running_window()
        for entry in heapq.nsmallest(BACKFILL_SCAN, self.beside):
            if self.expected[entry[1]] <= window:
                self.beside.remove(entry)
                heapq.heapify(self.beside)
                return self.jobs[entry[1]]
        return None

    def _starting(self, job: Job | None) -> Job | None:
        if job is not None:
            self.started[job.key] = time.monotonic()
            for other in self.needed_by.get(job.key, ()):
                if other in self.alone_keys and self.waiting[other] <= self.started.keys():
                    heapq.heappush(self.coming, (self.rank[other], other))
        return job

    def has_ready(self) -> bool:
        return bool(self.alone or self.beside)

    def next_ready(self) -> Job | None:
        """The first ready job, exclusive or not (on Dask a timing job keeps its host quiet itself)."""
        self._wake()
        heaps = [heap for heap in (self.alone, self.beside) if heap]
        return self.jobs[heapq.heappop(min(heaps, key=lambda heap: heap[0]))[1]] if heaps else None

    def ready_keys(self) -> list[str]:
        """The ready jobs' keys, first to start first."""
        return [key for _, key in sorted(self.alone + self.beside)]

    def _make_ready(self, key: str) -> None:
        heapq.heappush(self.alone if key in self.alone_keys else self.beside, (self.rank[key], key))

    def _wake(self) -> None:
        """Jobs another run held, whose pause is over, are ready again."""
        now = time.monotonic()
        for at, key in self.later:
            if at <= now:
                self._make_ready(key)
        self.later = [(at, key) for at, key in self.later if at > now]

    def done(self, key: str) -> None:
        self.settled.add(key)
        self.started.pop(key, None)
        for other in self.needed_by.get(key, ()):
            self.waiting[other].discard(key)
            if not self.waiting[other] and other not in self.settled:   # settled: not to start (blocked_by)
                self._make_ready(other)

    def retry_later(self, key: str) -> None:
        self.started.pop(key, None)
        self.later.append((time.monotonic() + BUSY_RETRY_S, key))

    def blocked_by(self, key: str) -> list[Job]:
        """Settle and return every job that depends on `key`."""
        self.settled.add(key)
        self.started.pop(key, None)
        blocked = dependents(self.graph, [key]) - self.settled
        self.settled |= blocked
        # `key` itself too: a job settled before it started (on Dask, one that no worker can take)
        self.alone = [entry for entry in self.alone if entry[1] not in self.settled]
        self.beside = [entry for entry in self.beside if entry[1] not in self.settled]
        heapq.heapify(self.alone)
        heapq.heapify(self.beside)
        return [self.jobs[k] for k in self.graph if k in blocked]

    def pending(self) -> list[Job]:
        """Jobs that never started."""
        return [job for key, job in self.jobs.items() if key not in self.settled]


def _seconds(value: float) -> float:
    """An estimate as the schedule can rank it: a finite number of seconds, at least 0."""
    seconds = float(value)
    return seconds if 0 <= seconds < math.inf else 0.0


def expected_seconds(store: Store) -> Callable[[Job], float]:
    """How long a job is expected to take: what it, or its kind, took on this store before, else what
    its kind says is typical (matrix.times.KindStats)."""
    stats = KindStats(store)
    return lambda job: stats.estimate(job.kind, job.name, job.params)


def runs_alone(job: Job) -> bool:
    """A timing job: nothing else runs beside it."""
    return KINDS.get(job.kind).runs_alone(job.params)


def run_local(statuses: list[JobStatus], store: Store, *, jobs: int = 1, keep_going: bool = False,
              kind_modules: Iterable[str] = (), display: Display | None = None) -> RunSummary:
    """Run every non-fresh job of `statuses` (in dependency order) on `jobs` worker processes."""
    display = display or NullDisplay()
    stale = [s.job for s in statuses if s.state != FRESH]
    summary = RunSummary(fresh=len(statuses) - len(stale))
    started = time.monotonic()
    if stale:
        replacing = results_to_replace(statuses)
        with _Pool(store, max(1, jobs), tuple(kind_modules), display, replacing) as pool, interrupt_at_safe_points():
            _drive(Schedule(stale, expected_seconds(store)), pool, summary, keep_going, display)
    summary.wall_s = time.monotonic() - started
    return summary


INTERRUPTED = threading.Event()   # set by SIGINT or SIGTERM inside interrupt_at_safe_points; the executors poll it
_STOP_SIGNAL = [signal.SIGINT]      # which of the two set it


@contextmanager
def interrupt_at_safe_points() -> Iterator[None]:
    """SIGINT (and SIGTERM, `kill PID`) set a flag that the driving loop turns into KeyboardInterrupt
    (`Terminated` for SIGTERM) between two waits: raised anywhere (inside concurrent.futures' wait,
    holding its locks) it could leave the pool unable to shut down, and the run hung; left to SIGTERM's
    default, the run died without a word and multiprocessing warned of leaked semaphores. A second
    signal stops at once, as Python's defaults do."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupted(signum, frame):
        _STOP_SIGNAL[0] = signum
        INTERRUPTED.set()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

    INTERRUPTED.clear()
    previous = {number: signal.signal(number, interrupted) for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def raise_interrupt() -> None:
    """Raise what the signal that set INTERRUPTED means: KeyboardInterrupt, or Terminated for SIGTERM."""
    raise Terminated() if _STOP_SIGNAL[0] == signal.SIGTERM else KeyboardInterrupt()


def _drive(schedule: Schedule, pool: _Pool, summary: RunSummary, keep_going: bool, display: Display) -> None:
    running: dict[Future, Job] = {}
    stopping = False
    while running or (schedule.has_work() and not stopping):
        if INTERRUPTED.is_set():
            raise_interrupt()
        exclusive = any(map(runs_alone, running.values()))
        while not stopping and (job := schedule.take(exclusive, len(running), pool.slots)):
            display.job_started(job)
            running[pool.submit(job)] = job
            exclusive = exclusive or runs_alone(job)
        finished, _ = wait(running, timeout=0.1, return_when=FIRST_COMPLETED)
        pool.drain_progress()
        for future in finished:
            job = running.pop(future)
            outcome = _outcome(job, future)
            if outcome.status == FAILED and pool.store.failure(job.key) is None:
                pool.store.record_failure(job.key, {"error": outcome.reason, "spec": job.spec()})
            if outcome.status == BUSY:
                display.job_waiting(job)
                schedule.retry_later(job.key)
                continue
            record_outcome(outcome, schedule, summary, display)
            stopping = stopping or (outcome.status == FAILED and not keep_going)
    for job in schedule.pending():
        record_outcome(Outcome(job.key, job.name, job.kind, NOT_STARTED,
                        "not started: the run stopped at the first failure (use --keep-going)"),
                schedule, summary, display)


def record_outcome(outcome: Outcome, schedule: Schedule, summary: RunSummary, display: Display) -> None:
    summary.outcomes.append(outcome)
    display.job_finished(outcome)
    if outcome.status == FAILED:
        for blocked in schedule.blocked_by(outcome.key):
            skipped = Outcome(blocked.key, blocked.name, blocked.kind, SKIPPED,
                              f"dependency failed: {outcome.name}")
            summary.outcomes.append(skipped)
            display.job_finished(skipped)
    else:
        schedule.done(outcome.key)


def _outcome(job: Job, future: Future) -> Outcome:
    try:
        answer = future.result()
    except KeyboardInterrupt:      # the job was interrupted: so is the run (what stopped it, said as such)
        if INTERRUPTED.is_set():
            raise_interrupt()
        raise
    except BrokenProcessPool:
        answer = {"status": FAILED, "reason": "the worker process died (out of memory or a crash)"}
    except Exception as error:  # an error in the engine's own worker code
        answer = {"status": FAILED, "reason": f"{type(error).__name__}: {error}"}
    return Outcome(job.key, job.name, job.kind, answer["status"], answer.get("reason", ""),
                   answer.get("duration_s", 0.0))


class _Pool:
    """A spawn-based process pool that is rebuilt if a worker dies, plus a progress queue."""

    def __init__(self, store: Store, slots: int, kind_modules: tuple, display: Display, replacing: dict[str, str]):
        self.store, self.slots, self.kind_modules, self.display = store, slots, kind_modules, display
        self.replacing = replacing   # forced jobs: key -> the stored result to run again
        self.run = uuid.uuid4().hex[:12]   # what this run hashed in full is not hashed again (matrix.store)
        self.context = multiprocessing.get_context("spawn")
        self.progress = self.context.Queue()
        self.executor = self._new_executor()

    def _new_executor(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(self.slots, mp_context=self.context, initializer=init_worker,
                                   initargs=(self.kind_modules, self.progress, worker_threads(self.slots)))

    def submit(self, job: Job) -> Future:
        arguments = (execute_job, str(self.store.root), job.spec(), (), self.replacing.get(job.key), self.run)
        try:
            return self.executor.submit(*arguments)
        except BrokenProcessPool:
            self.executor.shutdown(wait=False, cancel_futures=True)
            self.executor = self._new_executor()
            return self.executor.submit(*arguments)

    def _interrupt_workers(self) -> None:
        """An interrupt the driver alone got (`kill -INT PID`; a terminal's Ctrl-C reaches the workers too)
        is passed on to the workers still running after a moment, so their jobs stop as at Ctrl-C instead
        of running to their end while the run says nothing."""
        processes = list((getattr(self.executor, "_processes", None) or {}).values())   # the pool's own table
        deadline = time.monotonic() + INTERRUPT_GRACE_S
        while time.monotonic() < deadline and any(p.is_alive() for p in processes):
            time.sleep(0.05)
        for process in processes:
            if process.is_alive():
                try:
                    os.kill(process.pid, signal.SIGINT)
                except OSError:          # gone meanwhile
                    pass

    def drain_progress(self) -> None:
        while not self.progress.empty():
            try:
                key, update = self.progress.get_nowait()
            except Exception:  # queue.Empty, or a torn read at shutdown
                return
            self.display.job_progress(key, **update)

    def __enter__(self) -> _Pool:
        return self

    def __exit__(self, exc_type, *_) -> None:
        if exc_type is not None and issubclass(exc_type, KeyboardInterrupt):
            self._interrupt_workers()
        self.executor.shutdown(wait=True, cancel_futures=True)
        self.drain_progress()
        self.progress.close()


INTERRUPT_GRACE_S = 1.0   # a terminal's Ctrl-C stops the workers by itself within it


__all__ = ["run_local", "RunSummary", "Outcome", "DONE_ELSEWHERE"]
