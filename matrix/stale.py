"""Why a job must run: a short chain, as DVC's `Stage.changed`.

    own (params, code, inputs) -> dependencies -> outputs

Each link answers with reasons; an empty answer means the job is fresh. A job whose key has a
finished, intact result in the store is fresh whatever happened before (undoing an edit finds the
old results again), unless a dependency keeps its key but not its outputs: one forced to run again in
this plan (and so what stands on it), or one that ran again since this job read it and wrote other
outputs (each result records the outputs of the dependencies it was made from: a damaged output
rebuilt the same leaves what stands on it fresh). Otherwise the job's last spec under the
same name in this recipe's last run explains what changed.
"""
from __future__ import annotations

import os
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import Any

from matrix.jobs import Job, canonical_json, role_jobs
from matrix.store import CHANGED, INTACT, Store, outputs_token, result_token

FRESH, STALE, NEW = "fresh", "stale", "new"
NOT_STORED = "not in the store: the last run did not finish it, or it was removed since (gc, or by hand)"


@dataclass(frozen=True)
class JobStatus:
    job: Job
    state: str                  # fresh | stale | new
    reasons: tuple[str, ...]
    replaces: str | None = None  # forced: the token of the stored result the run is to replace

    @property
    def reason(self) -> str:
        return "; ".join(self.reasons)


def plan_statuses(jobs: list[Job], store: Store, previous: Mapping[str, dict],
                  forced_kinds: Collection[str] = (), listing: StoreListing | None = None) -> list[JobStatus]:
    """The status of each job of a plan (dependencies first)."""
    seen = PlanSoFar()
    return [seen.add(job_status(job, store, previous, forced_kinds, listing, seen)) for job in jobs]


@dataclass
class PlanSoFar:
    """What the jobs before this one in a plan found: the outputs of each fresh job's stored result,
    and the names of the jobs that run in this plan, whose outputs may be new: what stands on them runs
    again after them unless, by then, their outputs are the ones it was made from (see
    `if_dependencies_changed`)."""
    tokens: dict[str, str] = field(default_factory=dict)
    running: dict[str, str] = field(default_factory=dict)

    def add(self, status: JobStatus) -> JobStatus:
        if status.state != FRESH:
            self.running[status.job.key] = status.job.name
        return status

    def dependency_reruns(self, job: Job, result: dict) -> list[str]:
        """Why a stored result no longer stands on its dependencies' results (empty: it does)."""
        used = result.get("deps_used")
        again = [self.running[d.key] for d in job.dep_jobs() if d.key in self.running]
        if again:
            return [f"dependency runs again: {', '.join(dict.fromkeys(again))}"]
        if not isinstance(used, dict):   # a result from before results recorded their dependencies
            return []
        since = [d.name for d in job.dep_jobs() if d.key in self.tokens and used.get(d.key) != self.tokens[d.key]]
        return [f"dependency ran again since, with other outputs: {', '.join(dict.fromkeys(since))}"] if since else []


def job_status(job: Job, store: Store, previous: Mapping[str, dict],
               forced_kinds: Collection[str] = (), listing: StoreListing | None = None,
               seen: PlanSoFar | None = None) -> JobStatus:
    """`listing` (the store's keys read once for a whole plan) spares a job that is not stored the
    two files it would otherwise try to read; `seen` (the plan's statuses so far) checks that a fresh
    job's result was made from its dependencies' results as they are."""
    stored = listing is None or job.key in listing.stored
    result = store.result(job.key) if stored else None
    if job.kind in forced_kinds:
        return JobStatus(job, STALE, (f"forced (--force {job.kind})",), result and result_token(result))
    outputs = store.outputs_state(job.key, result) if result is not None else None
    if outputs == INTACT:
        reasons = seen.dependency_reruns(job, result) if seen is not None else []
        if reasons:   # runs again under the same key: the stored result is the one it replaces
            return JobStatus(job, STALE, tuple(reasons), if_dependencies_changed(result_token(result)))
        if seen is not None:
            seen.tokens[job.key] = outputs_token(result)
        return JobStatus(job, FRESH, ())
    if outputs == CHANGED:
        return JobStatus(job, STALE, ("output changed",))
    if result is not None:
        return JobStatus(job, STALE, ("output missing or corrupt",))
    if stored and store.job_dir(job.key).is_dir():
        return JobStatus(job, STALE, ("stored result missing or corrupt (result.json)",))   # not "new": it ran
    before = previous.get(job.name)
    failure = store.failure(job.key) if listing is None or job.key in listing.failed else None
    if failure is not None:
        return JobStatus(job, STALE, (f"failed last time: {failure.get('error', '?')}",))
    if before is None:
        return JobStatus(job, NEW, ("new",))
    reasons = own_changes(job, before) + dependency_changes(job, before)
    if not reasons:   # planned as it is by the last run, which ended before it ran, or removed since (it said "new")
        return JobStatus(job, NEW, (NOT_STORED,))
    return JobStatus(job, STALE, tuple(reasons))


@dataclass(frozen=True)
class StoreListing:
    stored: frozenset[str]      # keys with a job folder
    failed: frozenset[str]      # keys with a failure record

    @classmethod
    def of(cls, store: Store) -> StoreListing:
        failed = store.root / "failed"
        names = os.listdir(failed) if failed.is_dir() else []
        return cls(frozenset(store.keys()), frozenset(n[:-5] for n in names if n.endswith(".json")))


CONDITIONAL = "if-dependencies-changed:"


def if_dependencies_changed(token: str) -> str:
    """What a job standing on one that runs again replaces: its stored result (`token`), unless, when
    its turn comes, that result was made from its dependencies' outputs as they are then (a rebuild
    with the same outputs, a forced run that measured the same): then the worker keeps it."""
    return CONDITIONAL + token


def results_to_replace(statuses: list[JobStatus]) -> dict[str, str]:
    """Forced jobs: job key -> the token of the stored result the run is to replace."""
    return {s.job.key: s.replaces for s in statuses if s.replaces}


def own_changes(job: Job, before: dict) -> list[str]:
    reasons = []
    diffs = _diff(before.get("params", {}), dict(job.params))
    if diffs:
        reasons.append("params changed: " + ", ".join(diffs[:3]) + (" …" if len(diffs) > 3 else ""))
    if before.get("code") != job.code:
        reasons.append(f"code changed ({job.kind})")
    old_inputs = before.get("inputs", {})
    changed = sorted(role for role, f in job.inputs.items() if old_inputs.get(role, {}).get("sha256") != f.sha256)
    if changed:
        reasons.append("input changed: " + ", ".join(f"{r} ({_changed_files(job.inputs[r], old_inputs.get(r, {}))})"
                                                     for r in changed))
    return reasons


def _changed_files(now, before: dict) -> str:
    """Which files of an input changed: those of its parts whose hash differs (or that came or went), when
    both it and the stored record have parts; else its path."""
    old = before.get("parts")
    if not now.parts or not isinstance(old, dict):
        return now.path
    new = dict(now.parts)
    return ", ".join(name for name in sorted(set(new) | set(old)) if new.get(name) != old.get(name)) or now.path


def dependency_changes(job: Job, before: dict) -> list[str]:
    old = before.get("deps", {})
    # a role the job has now and had not, or had and has no more (an outside test read "not in the store")
    added = [f"{role} ({', '.join(d.name for d in role_jobs(job.deps[role]))})" for role in job.deps if role not in old]
    removed = [role for role in old if role not in job.deps]
    reasons = ([f"dependency added: {', '.join(added)}"] if added else []) + \
        ([f"dependency removed: {', '.join(removed)}"] if removed else [])
    changed = [d.name for role, dep in job.deps.items() if role in old
               for d in role_jobs(dep) if d.key not in _flat(old.get(role))]
    if changed or reasons:
        return reasons + ([f"dependency changed: {', '.join(dict.fromkeys(changed))}"] if changed else [])
    # the same jobs in another order: a group's order is part of what a job is made from (a training's recordings)
    reordered = [role for role, dep in job.deps.items() if isinstance(dep, tuple)
                 and [d.key for d in dep] != _flat(old.get(role))]
    return [f"dependencies reordered: {', '.join(reordered)} (a group's order is part of the job)"] if reordered else []


def _flat(value: Any) -> list:
    return value if isinstance(value, list) else [value]


def _diff(old: Any, new: Any, prefix: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for key in sorted(set(old) | set(new), key=str):
            where = f"{prefix}.{key}" if prefix else str(key)
            if key not in old:
                out.append(f"{where} added ({_short(new[key])})")
            elif key not in new:
                out.append(f"{where} removed")
            else:
                out.extend(_diff(old[key], new[key], where))
        return out
    if canonical_json(old) != canonical_json(new):
        return [f"{prefix or 'value'} {_short(old)} -> {_short(new)}"]
    return []


def _short(value: Any) -> str:
    text = canonical_json(value)
    return text if len(text) <= 30 else text[:27] + "..."
