"""The engine's operations: open a store, plan a recipe, run the plan, collect garbage.

An executor (matrix.execute's process pool, matrix.dask_executor's cluster) is imported when a plan
runs: planning never needs one, and the pool's multiprocessing and concurrent.futures cost `plan`
~0.03 s to import."""
from __future__ import annotations

import gc
import importlib
import os
import re
import shutil
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from matrix.dag import in_order
from matrix.errors import MatrixError, did_you_mean
from matrix.jobs import spec_dep_keys
from matrix.kinds import KINDS
from matrix.recipe import Domain, Recipe
from matrix.runs import RunSummary
from matrix.stale import FRESH, JobStatus, StoreListing, plan_statuses
from matrix.store import Store, read_json, write_json_atomic


TRASH_GRACE_S = 60.0


def open_store(domain: Domain, root: str | Path | None = None) -> Store:
    """The store at `root`, else $<domain.store_env>, else the domain's default folder; a file there is an error
    (every command would read it as an empty store, and `run` fail to make its folders)."""
    given = root or os.environ.get(domain.store_env)
    folder = Path(given or domain.default_store)
    if folder.exists() and not folder.is_dir():
        how = "--store" if root else f"${domain.store_env}" if given else "the default store"
        raise MatrixError(f"{how} {folder}: a file, not a store folder; give a folder (a new one is made)")
    return Store(folder)


def register_kinds(domain: Domain) -> None:
    for module in domain.kind_modules:
        importlib.import_module(module)


def slug(name: str) -> str:
    """A file-name-safe form of a recipe name."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "recipe"


@dataclass(frozen=True)
class Plan:
    recipe: Recipe
    statuses: list[JobStatus]          # dependencies first
    previous: dict[str, dict] = field(default_factory=dict)   # job name -> the spec its reasons compare with

    @property
    def stale(self) -> list[JobStatus]:
        return [s for s in self.statuses if s.state != FRESH]

    def counts(self) -> dict[str, Counter]:
        counts: dict[str, Counter] = {}
        for status in self.statuses:
            counts.setdefault(status.job.kind, Counter())[status.state] += 1
        return counts


def plan_jobs(recipe: Recipe, domain: Domain) -> list:
    """Every job the recipe needs (dependencies first), with names checked to be unique."""
    register_kinds(domain)
    jobs = in_order(domain.plan(recipe))
    seen: dict[str, str] = {}
    for job in jobs:
        if seen.setdefault(job.name, job.key) != job.key:
            raise MatrixError(f"two different jobs are both named {job.name!r}; job names must be unique "
                              "within a recipe (a bug in the domain's planner)")
    return jobs


FREEZE_FROM_JOBS = 10_000   # plans this large freeze what is alive after them (_CollectorPaused)


def make_plan(recipe: Recipe, domain: Domain, store: Store, force: Iterable[str] = ()) -> Plan:
    with _CollectorPaused() as paused:
        jobs = plan_jobs(recipe, domain)
        paused.freeze = len(jobs) >= FREEZE_FROM_JOBS
        forced = _check_forced(force)
        listing = StoreListing.of(store)
        previous = _previous_specs(read_json(store.recipe_path(slug(recipe.name))), listing)
        return Plan(recipe, plan_statuses(jobs, store, previous, forced, listing), previous)


def _previous_specs(record: dict | None, listing: StoreListing) -> dict[str, dict]:
    """Per job name, the spec of the recipe's last run, or, where that run ended (interrupted, failed)
    before the job of that name ran, the version before it, which the store holds (`before`): what an
    unfinished edit changed is still said after the run that began it stopped."""
    record = record if isinstance(record, dict) else {}
    previous = dict(record.get("jobs") or {})
    for name, spec in (record.get("before") or {}).items():
        if (previous.get(name) or {}).get("key") not in listing.stored:
            previous[name] = spec
    return previous


def _unfinished_before(plan: Plan) -> dict[str, dict]:
    """The specs a run's record keeps beside its jobs: for each job that is to run, the version of that
    name before this plan, where it differs."""
    before = {}
    for status in plan.stale:
        spec = plan.previous.get(status.job.name)
        if spec is not None and spec.get("key") != status.job.key:
            before[status.job.name] = spec
    return before


class _CollectorPaused:
    """Python's cycle collector paused: a plan makes a few objects a job and no cycles, and the collector
    would walk every object made so far again and again as they pile up (a quarter of the time of a
    100,000-job plan). After a plan of FREEZE_FROM_JOBS jobs or more, every object alive is frozen
    (gc.freeze: left out of later collections, still freed by reference counting) rather than walked once
    more when collecting resumes (another 6 % of such a plan). Not after a smaller one, where that walk is
    short: a cycle left for the collector at that moment would never be collected, and a long-lived
    process (the tests, a Dask client) plans many times."""

    def __init__(self) -> None:
        self.freeze = False

    def __enter__(self) -> _CollectorPaused:
        self.was_enabled = gc.isenabled()
        gc.disable()
        return self

    def __exit__(self, *exc_info) -> None:
        if self.was_enabled:
            if self.freeze:
                gc.freeze()
            gc.enable()


def _check_forced(kinds: Iterable[str]) -> set[str]:
    kinds = set(kinds)
    for kind in kinds:
        if kind not in KINDS:
            raise MatrixError(f"--force {kind}: unknown job kind{did_you_mean(kind, KINDS)}; "
                              f"kinds: {', '.join(KINDS)}")
    return kinds


@dataclass(frozen=True)
class Executor:
    """Where jobs run: "local" (a process pool), "dask" (a running scheduler) or "dask-local"."""
    kind: str = "local"
    jobs: int = 1
    scheduler: str | None = None
    timing_resource: str | None = None

    def __post_init__(self) -> None:
        if self.jobs < 1:
            raise MatrixError(f"-j/--jobs {self.jobs}: give 1 or more jobs at once")
        if self.kind == "dask" and not self.scheduler:
            raise MatrixError("--executor dask needs --scheduler ADDRESS (or use --executor dask-local)")
        if self.scheduler and self.kind != "dask":
            raise MatrixError(f"--scheduler {self.scheduler} is for --executor dask; the executor is {self.kind!r}")
        if self.timing_resource and not self.kind.startswith("dask"):
            raise MatrixError("--timing-resource places jobs on Dask workers; use it with --executor dask")


def run_plan(plan: Plan, domain: Domain, store: Store, *, jobs: int = 1, keep_going: bool = False,
             display=None, executor: Executor | None = None) -> RunSummary:
    """Record the recipe's jobs (for reasons and gc), then run the stale ones; gc waits for the run to end
    (`Store.running`): what the run has finished, its later jobs read."""
    with store.running():
        return _record_and_run(plan, domain, store, executor or Executor("local", jobs), keep_going, display)


def _record_and_run(plan: Plan, domain: Domain, store: Store, executor: Executor, keep_going: bool,
                    display) -> RunSummary:
    for leftover in leftovers(store):   # of killed runs; never a folder a running job holds
        shutil.rmtree(leftover, ignore_errors=True)
    write_json_atomic(store.recipe_path(slug(plan.recipe.name)),
                      {"recipe": plan.recipe.name, "file": plan.recipe.file, "written_at": time.time(),
                       "jobs": {s.job.name: s.job.spec() for s in plan.statuses}, "before": _unfinished_before(plan)})
    if not plan.stale:   # recorded all the same: the recipe's last run is this one (plan's reasons, status --recipe)
        return RunSummary(fresh=len(plan.statuses))
    if display is not None:
        display.start(s.job for s in plan.stale)
    try:
        if executor.kind == "local":
            return _run_here(plan, domain, store, executor, keep_going, display)
        return _run_on_dask(plan, domain, store, executor, keep_going, display)
    finally:
        if display is not None:
            display.stop()


def _run_here(plan: Plan, domain: Domain, store: Store, executor: Executor, keep_going: bool,
              display) -> RunSummary:
    from matrix import execute
    return execute.run_local(plan.statuses, store, jobs=executor.jobs, keep_going=keep_going,
                             kind_modules=domain.kind_modules, display=display)


def _run_on_dask(plan: Plan, domain: Domain, store: Store, executor: Executor, keep_going: bool,
                 display) -> RunSummary:
    from matrix import dask_executor
    if executor.kind not in ("dask", "dask-local"):
        raise MatrixError(f"unknown executor {executor.kind!r}; use local, dask or dask-local")
    if executor.kind == "dask" and not executor.scheduler:
        raise MatrixError("--executor dask needs --scheduler ADDRESS (or use --executor dask-local -j N)")
    with dask_executor.connect(executor.scheduler if executor.kind == "dask" else None, executor.jobs) as client:
        return dask_executor.run_dask(plan.statuses, store, client, keep_going=keep_going,
                                      kind_modules=domain.kind_modules,
                                      timing_resource=executor.timing_resource, display=display)


@dataclass(frozen=True)
class Garbage:
    keys: list[str]
    temp: list[Path]
    bytes: int
    elsewhere: dict[str, str] = field(default_factory=dict)   # unreached, kept: key -> why (Domain.kept_elsewhere)
    work: dict[str, Path] = field(default_factory=dict)       # a failed job's work folder, removed with it


def find_garbage(store: Store, keep: set[str], kept_elsewhere: Callable[[dict], str | None] | None = None) -> Garbage:
    """Stored jobs no kept recipe reaches (but those `kept_elsewhere` keeps), failure records, and leftovers
    of killed runs."""
    unreached = [key for key in store.keys() if key not in keep]
    elsewhere = {key: why for key in unreached
                 if kept_elsewhere and (why := kept_elsewhere(store.spec(key) or {}))}
    keep = set(keep) | _stood_on(store, elsewhere)   # what the jobs kept for elsewhere were made from
    keys = [key for key in unreached if key not in keep]
    failed = [p.stem for p in (store.root / "failed").glob("*.json") if p.stem not in keep]
    kept_for_failures = failure_workdirs(store)   # not a killed run's: a failed job's, kept for its log
    work = {key: kept_for_failures[key] for key in failed if key in kept_for_failures}
    temp = [p for p in leftovers(store) if p.resolve() not in kept_for_failures.values()]
    size = sum(_size(store.job_dir(k)) for k in keys) + sum(_size(p) for p in [*temp, *work.values()])
    return Garbage(sorted(set(keys) | set(failed)), temp, size, elsewhere, work)


def failure_workdirs(store: Store) -> dict[str, Path]:
    """Failed job key -> the work folder its failure record names, where it is still in the store's tmp/."""
    found = {}
    for record in (store.root / "failed").glob("*.json"):
        workdir = (store.failure(record.stem) or {}).get("workdir")
        folder = Path(workdir).resolve() if isinstance(workdir, str) else None
        if folder is not None and folder.parent == (store.root / "tmp").resolve() and folder.is_dir():
            found[record.stem] = folder
    return found


def _stood_on(store: Store, keys: Iterable[str]) -> set[str]:
    """`keys` and every stored job they depend on, transitively (read from their spec.json)."""
    found, stack = set(), list(keys)
    while stack:
        key = stack.pop()
        if key in found:
            continue
        found.add(key)
        stack += spec_dep_keys((store.spec(key) or {}).get("deps", {}))
    return found


def collect_garbage(store: Store, garbage: Garbage) -> list[str]:
    """Remove the garbage; returns the keys removed (a job another process holds stays)."""
    removed = []
    for key in garbage.keys:
        with store.lock(key) as held:
            if held:
                store.remove(key)
                (store.root / "locks" / f"{key}.lock").unlink(missing_ok=True)
                if key in garbage.work:
                    shutil.rmtree(garbage.work[key], ignore_errors=True)
                removed.append(key)
    for path in garbage.temp:
        shutil.rmtree(path, ignore_errors=True)
    return removed


def leftovers(store: Store) -> list[Path]:
    """Folders in the store's tmp/ that no running job holds: what killed runs left behind."""
    tmp = store.root / "tmp"
    return [p for p in sorted(tmp.iterdir()) if not _in_flight(store, p)] if tmp.is_dir() else []


def _in_flight(store: Store, temp: Path) -> bool:
    """A job's temp folder is in flight while a lock whose key starts like it is held; a trash
    folder while it is young (its writer is deleting it)."""
    if temp.name.startswith("trash-"):
        try:
            return time.time() - temp.stat().st_mtime < TRASH_GRACE_S
        except OSError:
            return True              # gone already
    prefix = temp.name.split("-", 1)[0]
    return any(store.is_locked(p.stem) for p in (store.root / "locks").glob(f"{prefix}*.lock"))


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else 0
