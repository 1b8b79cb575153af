"""Running the stale part of a plan on a Dask cluster that shares the job store.

The driver keeps the same schedule as the local executor (`matrix.execute.Schedule`): each stale job
becomes one Dask future when its dependencies are done (Dask places it), and a failed job's dependents
are skipped. Each task runs the same `matrix.worker.execute_job` as the local executor, writing to the
shared store. The store stays the source of truth: a driver restarted later plans from it, and a worker
that dies mid-job leaves only a temporary folder behind (Dask reruns the task elsewhere; the lock dies
with the process).

A timing (exclusive) job has its host to itself, not the cluster: it is submitted like any other job,
and on its worker it takes its host's lock alone (matrix.hostlock), so no other job starts on that
host's workers until it is done (one that was given to a worker of that host waits there), while
the other hosts go on working; timing jobs on different hosts run at once.

Placement: a job kind's `resources` and `resources_for(params)` (for example {"GPU": 1}, or the worker
resource a hardware profile names) become Dask resources, so such jobs go only to workers started with
`--resources GPU=1`; with `timing_resource="TIMING"`, every exclusive (timing) job goes only to
workers declaring TIMING, so timings come from one class of machine.
"""
from __future__ import annotations

import ctypes
import functools
import os
import signal
import threading
import time
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

from matrix.display import NullDisplay
from matrix.errors import MatrixError
from matrix.execute import (BUSY_RETRY_S, INTERRUPTED, Schedule, expected_seconds, interrupt_at_safe_points,
                            raise_interrupt, record_outcome)
from matrix.jobs import Job
from matrix.kinds import KINDS
from matrix.runs import FAILED, NOT_STARTED, SKIPPED, Outcome, RunSummary, worker_threads
from matrix.stale import FRESH, JobStatus, results_to_replace
from matrix.store import Store
from matrix.worker import THREAD_VARIABLES, execute_job

INSTALL_HINT = "the Dask executor needs Dask distributed: pip install distributed"


def import_distributed():
    try:
        import distributed
    except ImportError:
        raise MatrixError(INSTALL_HINT) from None
    return distributed


def connect(scheduler: str | None, workers: int = 2):
    """A Client on `scheduler`, or on a new LocalCluster of `workers` single-threaded processes."""
    distributed = import_distributed()
    if scheduler:
        try:
            return distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as error:
            raise MatrixError(f"cannot reach the Dask scheduler at {scheduler}: {error}") from None
        except ValueError as error:   # not an address at all (a port that is not a number, a URL)
            raise MatrixError(f"--scheduler {scheduler}: not a Dask scheduler address ({error}); give "
                              "tcp://HOST:PORT, e.g. tcp://127.0.0.1:8786") from None
    with _sigint_ignored():   # the workers it starts keep it: Ctrl-C is the driver's (it closes the cluster)
        cluster = distributed.LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=True,
                                           dashboard_address=None, env=_thread_share(workers))
    return distributed.Client(cluster)


def _thread_share(workers: int) -> dict[str, str]:
    """The math libraries' thread variables of a local worker, as the local executor's pool sets them
    (matrix.worker.init_worker): each worker its share of the cores, so that two do not spin against each
    other; a variable the user set is kept."""
    threads = worker_threads(max(1, workers))
    return {name: os.environ.get(name, str(threads)) for name in THREAD_VARIABLES} if threads else {}


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while processes are started (an ignored signal stays ignored in the child), so that
    Ctrl-C, which the terminal sends to every process of the group, reaches only the driver: the workers
    printed a traceback each."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def check_single_threaded(client) -> None:
    """One job at a time per worker process: a job sets process-wide state (its threads' count, the
    modules it imports), so two jobs in one process's threads would run with each other's."""
    workers = client.scheduler_info().get("workers", {})
    threaded = sorted(f"{address} ({info.get('nthreads')} threads)" for address, info in workers.items()
                      if (info.get("nthreads") or 1) > 1)
    if threaded:
        raise MatrixError(f"Dask worker(s) {', '.join(threaded)} run several jobs at once in one process, which "
                          "jobs do not allow (each sets its process's thread count and imports): start workers "
                          "with `dask worker ADDRESS --nthreads 1` (--nworkers N for more processes)")


# glibc's mallopt parameters, and the largest thresholds its dynamic adjustment reaches on 64-bit
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD_MAX, TRIM_THRESHOLD_MAX = 32 << 20, 64 << 20


@functools.cache
def _malloc_as_a_plain_process() -> None:
    """Undo what the Dask nanny's MALLOC_TRIM_THRESHOLD_ (distributed.nanny.pre-spawn-environ) does to
    glibc's malloc: a threshold set at all turns off its dynamic mmap threshold, so every allocation above
    128 KiB is a fresh mmap, page faults and all. An outside test timed torch's eager PilotNet at 4 ms on a
    Dask worker against 1.2-1.9 ms with the local executor (2.2 against 0.95 ms alone): the thresholds
    the dynamic adjustment would reach, set once per worker process (no-op off glibc)."""
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_MAX)
        libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_MAX)
    except (OSError, AttributeError):   # not glibc
        pass


def missing_resources(client, jobs: list[Job], timing_resource: str | None) -> dict[str, str]:
    """{job key: a resource it needs that no worker of the cluster declares}: such a job would wait for
    ever, the run showing "about 0:00:04 left" (an outside test); it is not started, saying why."""
    workers = client.scheduler_info().get("workers", {}).values()
    held = {name for info in workers for name in info.get("resources") or {}}
    return {job.key: name for job in jobs for name in _resources(job, timing_resource) if name not in held}


def _not_placeable(missing: dict[str, str], schedule: Schedule, summary: RunSummary, display) -> None:
    """Record the jobs no worker can take as not started (and the jobs that stand on them as skipped)."""
    for key, resource in missing.items():
        if key in schedule.settled:   # skipped already: it stands on another such job
            continue
        job = schedule.jobs[key]
        blocked = schedule.blocked_by(key)
        why = (f"not started: no worker of the Dask cluster declares the resource {resource!r} (start one with "
               f"`dask worker ADDRESS --nthreads 1 --resources \"{resource}=1\"`)")
        outcomes = [Outcome(key, job.name, job.kind, NOT_STARTED, why)]
        outcomes += [Outcome(other.key, other.name, other.kind, SKIPPED, f"dependency not started: {job.name}")
                     for other in blocked]
        for outcome in outcomes:
            summary.outcomes.append(outcome)
            display.job_finished(outcome)


def run_task(store_root: str, spec: dict, kind_modules: tuple, replaces: str | None, topic: str | None = None,
             run: str | None = None) -> dict:
    """The Dask task: run the job (locked, atomic); wait while another run holds it. With `topic`, the
    job's start and its progress go to the driver as events on it (its display shows what runs); `run`
    names the run (matrix.worker.execute_job)."""
    _malloc_as_a_plain_process()
    if topic is not None:
        _send_progress_to(topic, spec["key"])
    while True:
        answer = execute_job(store_root, spec, kind_modules, replaces, run)
        if answer["status"] != "busy":  # another run holds the job: wait for it, then read its result
            return {**answer, "name": spec["name"]}
        time.sleep(0.2)


def run_dask(statuses: list[JobStatus], store: Store, client, *, keep_going: bool = False,
             kind_modules: Iterable[str] = (), timing_resource: str | None = None,
             display=None) -> RunSummary:
    """Submit each stale job once its dependencies are done; a timing (exclusive) job keeps its own host
    quiet on the worker (see the module); with `timing_resource` it also runs only on the workers that
    declare it."""
    check_single_threaded(client)
    display = display or NullDisplay()
    stale = [s.job for s in statuses if s.state != FRESH]
    summary = RunSummary(fresh=len(statuses) - len(stale))
    started = time.monotonic()
    submit = _Submitter(client, store, tuple(kind_modules), timing_resource, results_to_replace(statuses))
    schedule = Schedule(stale, expected_seconds(store))
    _not_placeable(missing_resources(client, stale, timing_resource), schedule, summary, display)
    events = _ProgressEvents(client, display, {job.key: job for job in stale}, submit.topic)
    try:
        with interrupt_at_safe_points():
            _drive(schedule, submit, client, summary, keep_going, display, events)
    finally:
        events.close()
    for job in schedule.pending():
        record_outcome(Outcome(job.key, job.name, job.kind, NOT_STARTED, not_finished_reason(client)),
                       schedule, summary, display)
    summary.wall_s = time.monotonic() - started
    return summary


def _drive(schedule: Schedule, submit, client, summary: RunSummary, keep_going: bool, display, events) -> None:
    finished, running = import_distributed().as_completed(), {}
    stopping = False
    while running or (schedule.has_work() and not stopping):
        while not stopping and (job := schedule.next_ready()):
            future = submit(job)
            running[future.key] = job
            finished.add(future)
        future = _next_finished(finished, client, running)
        if future is None:   # nothing ended yet, or only jobs another run holds (retried after a pause)
            continue
        job = running.pop(future.key)
        events.job_finished(job.key)
        outcome = _outcome(job, future, client)
        record_outcome(outcome, schedule, summary, display)
        stopping = stopping or (outcome.status == FAILED and not keep_going)


def _next_finished(finished, client, running: dict):
    """The next future to end, or None after a short wait; Ctrl-C (a flag set by the handler: raised inside
    Dask's waits it could leave the client stuck) cancels the running jobs and interrupts the run, as the
    local executor does: the jobs in flight are lost, not half-written (each commits atomically)."""
    if INTERRUPTED.is_set():
        client.cancel(list(finished.futures))   # those not ended yet
        raise_interrupt()
    if finished.has_ready() or (running and _wait_for_one(finished)):
        return next(finished)
    time.sleep(BUSY_RETRY_S if not running else 0)
    return None


def _send_progress_to(topic: str, key: str) -> None:
    """Events for the driver (Client.subscribe_topic): the job started, then its progress updates
    (matrix.worker's progress sink: one job at a time in a worker process, check_single_threaded)."""
    import distributed
    from matrix import worker
    dask_worker = distributed.get_worker()
    worker._progress_sink = lambda job_key, update: dask_worker.log_event(topic, (job_key, update))
    dask_worker.log_event(topic, (key, {STARTED: True}))


STARTED = "started"


class _ProgressEvents:
    """The driver's side of the tasks' events: the display learns which jobs run and how far they are
    (Dask hands a job to a worker when it sees fit; submitted is not running). An event that arrives
    after its job's result is dropped."""

    def __init__(self, client, display, jobs: dict[str, Job], topic: str):
        self.client, self.display, self.jobs, self.topic = client, display, jobs, topic
        self.finished: set[str] = set()
        self.lock = threading.Lock()
        client.subscribe_topic(topic, self.on_event)

    def on_event(self, event) -> None:
        key, update = event[1]
        with self.lock:
            if key in self.finished or key not in self.jobs:
                return
            if update.get(STARTED):
                self.display.job_started(self.jobs[key])
            else:
                self.display.job_progress(key, **update)

    def job_finished(self, key: str) -> None:
        with self.lock:
            self.finished.add(key)

    def close(self) -> None:
        self.client.unsubscribe_topic(self.topic)


def _wait_for_one(finished, seconds: float = 0.1) -> bool:
    end = time.monotonic() + seconds
    while not finished.has_ready() and time.monotonic() < end:
        time.sleep(0.01)
    return finished.has_ready()


class _Submitter:
    def __init__(self, client, store: Store, kind_modules: tuple, timing_resource: str | None,
                 replacing: dict[str, str]):
        self.client, self.kind_modules, self.timing_resource = client, kind_modules, timing_resource
        self.root, self.run, self.replacing = str(store.root.resolve()), uuid.uuid4().hex[:12], replacing

    @property
    def topic(self) -> str:
        return f"matrix-progress-{self.run}"

    def __call__(self, job: Job):
        return self.client.submit(run_task, self.root, job.spec(), self.kind_modules, self.replacing.get(job.key),
                                  self.topic, self.run, key=_task_key(job, self.run), pure=False,
                                  resources=_resources(job, self.timing_resource) or None)


def _task_key(job: Job, run: str) -> str:
    """The Dask key of a job in this run. Not the bare job key: Dask hands back a task it still
    holds under the same key (from an earlier run, perhaps on another store) instead of running it.
    The kind comes first, so Dask's dashboard groups tasks by kind."""
    return f"{job.kind}-{run}-{job.key}"


def _resources(job: Job, timing_resource: str | None) -> dict[str, float]:
    kind = KINDS.get(job.kind)
    resources = dict(kind.resources)
    if kind.resources_for is not None:
        resources.update(kind.resources_for(job.params))
    if timing_resource and kind.runs_alone(job.params):
        resources[timing_resource] = 1
    return resources


STOPPED = "not started: the run stopped at the first failure (use --keep-going)"


def not_finished_reason(client) -> str:
    """Why a job of the run did not finish: the run stopped at a failure, or (an outside test: every job
    said that, with no failure anywhere) the connection to the scheduler was lost."""
    if getattr(client, "status", "running") == "running":
        return STOPPED
    address = getattr(getattr(client, "scheduler", None), "address", None) or "its address"
    return (f"not finished: the connection to the Dask scheduler ({address}) was lost; a job that finished on a "
            "worker meanwhile is in the store (run again: it is fresh)")


def _outcome(job: Job, future, client=None) -> Outcome:
    if future.cancelled():
        return Outcome(job.key, job.name, job.kind, NOT_STARTED, not_finished_reason(client))
    try:
        answer = future.result()
    except Exception as error:  # the task itself broke (for example a worker died too often)
        answer = {"status": FAILED, "reason": f"{type(error).__name__}: {error}"}
    return Outcome(job.key, job.name, job.kind, answer["status"], answer.get("reason", ""),
                   answer.get("duration_s", 0.0))
