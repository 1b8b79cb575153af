"""Running the stale part of a plan on a Dask cluster that shares the job store.

Each stale job becomes one Dask future whose arguments include the futures of its dependencies, so
Dask orders the work and places it; each task runs the same `matrix.worker.execute_job` as the
local executor, writing to the shared store. The store stays the source of truth: a driver
restarted later plans from it, and a worker that dies mid-job leaves only a temporary folder behind
(Dask reruns the task elsewhere; the lock dies with the process).

Placement: a job kind's `resources` (for example {"GPU": 1}) become Dask resources, so such jobs go
only to workers started with `--resources GPU=1`; with `timing_resource="TIMING"`, exclusive
(timing) jobs go only to workers declaring TIMING, so timings come from one class of machine.
"""
from __future__ import annotations

import time
import uuid
from collections.abc import Iterable

from matrix.errors import MatrixError
from matrix.execute import NOT_STARTED, SKIPPED, Outcome, RunSummary
from matrix.jobs import Job
from matrix.kinds import KINDS
from matrix.stale import FRESH, JobStatus, results_to_replace
from matrix.store import Store
from matrix.worker import FAILED, execute_job

INSTALL_HINT = "the Dask executor needs Dask distributed: pip install distributed"
BLOCKING = (FAILED, SKIPPED, NOT_STARTED)


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
    cluster = distributed.LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    return distributed.Client(cluster)


def run_task(store_root: str, spec: dict, kind_modules: tuple, replaces: str | None, *deps: dict) -> dict:
    """The Dask task: skip when a dependency failed, else run the job (locked, atomic)."""
    for dep in deps:
        if dep["status"] in BLOCKING:
            return {"status": SKIPPED, "reason": f"dependency failed: {dep['name']}", "name": spec["name"]}
    while True:
        answer = execute_job(store_root, spec, kind_modules, replaces)
        if answer["status"] != "busy":  # another run holds the job: wait for it, then read its result
            return {**answer, "name": spec["name"]}
        time.sleep(0.2)


def run_dask(statuses: list[JobStatus], store: Store, client, *, keep_going: bool = False,
             kind_modules: Iterable[str] = (), timing_resource: str | None = None,
             display=None) -> RunSummary:
    distributed = import_distributed()
    stale = [s.job for s in statuses if s.state != FRESH]
    summary = RunSummary(fresh=len(statuses) - len(stale))
    started = time.monotonic()
    replacing = results_to_replace(statuses)
    futures = _submit(client, stale, store, tuple(kind_modules), timing_resource, replacing)
    jobs = {future.key: job for job, future in zip(stale, futures.values())}
    stopping = False
    for future in distributed.as_completed(list(futures.values())):
        job = jobs[future.key]
        outcome = _outcome(job, future)
        summary.outcomes.append(outcome)
        if display is not None:
            display.job_finished(outcome)
        if outcome.status == FAILED and not keep_going and not stopping:
            stopping = True
            client.cancel([f for f in futures.values() if not f.done()])
    summary.wall_s = time.monotonic() - started
    return summary


def _submit(client, stale: list[Job], store: Store, kind_modules: tuple, timing_resource: str | None,
            replacing: dict[str, str]) -> dict:
    futures: dict[str, object] = {}
    root, run = str(store.root.resolve()), uuid.uuid4().hex[:12]
    for job in stale:  # dependencies first, so their futures exist
        deps = [futures[d.key] for d in job.dep_jobs() if d.key in futures]
        futures[job.key] = client.submit(run_task, root, job.spec(), kind_modules, replacing.get(job.key), *deps,
                                         key=_task_key(job, run),
                                         pure=False, resources=_resources(job, timing_resource) or None)
    return futures


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
    if timing_resource and kind.exclusive:
        resources[timing_resource] = 1
    return resources


def _outcome(job: Job, future) -> Outcome:
    if future.cancelled():
        return Outcome(job.key, job.name, job.kind, NOT_STARTED,
                       "not started: the run stopped at the first failure (use --keep-going)")
    try:
        answer = future.result()
    except Exception as error:  # the task itself broke (for example a worker died too often)
        answer = {"status": FAILED, "reason": f"{type(error).__name__}: {error}"}
    return Outcome(job.key, job.name, job.kind, answer["status"], answer.get("reason", ""),
                   answer.get("duration_s", 0.0))
