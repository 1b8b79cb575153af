"""Job kinds: the domain registers a handler per kind; the engine runs it in a worker.

    class TrainParams(pydantic.BaseModel):       # the one home of the kind's params and defaults
        model_config = pydantic.ConfigDict(extra="forbid", frozen=True)
        epochs: int = 20

    register_kind("train", "mydomain.jobs.train:run_train", params=TrainParams)

    # mydomain/jobs/train.py: imported only when a job runs, so it may import heavy libraries at its top
    def run_train(ctx: JobContext) -> dict:
        ctx.spec.epochs          # the validated params; ctx.deps["data"].artifacts; write into ctx.out
        return {"val_mse": 0.01} # JSON-serialisable result

The kind's code fingerprint is the import closure of the handler's module within its top-level
package, read from the source (nothing is imported to plan), so an edit to any module the handler
can reach changes the keys of its jobs. `code=` adds what no import statement names.

A handler raises `NotApplicable(reason)` when the job cannot run on this hardware: the result is
recorded (and cached) as "not applicable: reason", and jobs that depend on it get the same status
without running.

`typical_s=30` (or `typical_for=lambda params: 3.0 * params["epochs"]`) says what a job of the kind
typically takes: until a store has run it, the scheduler orders ready jobs and fills an idle core with
it (matrix.execute.Schedule), and the time left starts from it. A guess only, never in a key: given at
registration, it is written in the kind's own module, which is its code (tuning it re-keys the kind's
jobs); `guess_kind(name, typical_for=...)` gives it from a module that no handler imports.
"""
from __future__ import annotations

import importlib
import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import ModuleType
from functools import cached_property
from typing import Any

import pydantic

from matrix.errors import MatrixError, did_you_mean
from matrix.fingerprint import cache_generation, closure_fingerprint, module_closure
from matrix.registry import Registry


class NotApplicable(MatrixError):
    """Raised by a handler: this job cannot run here (for example a CUDA strategy on a CPU host)."""


@dataclass(frozen=True)
class DepResult:
    """What a handler sees of one finished dependency."""
    key: str
    kind: str
    params: Mapping[str, Any]
    result: Mapping[str, Any]
    artifacts: Path
    name: str = ""
    status: str = "ok"             # ok | not_applicable
    reason: str = ""


ProgressFn = Callable[..., None]


@dataclass
class JobContext:
    key: str
    kind: str
    name: str
    params: Mapping[str, Any]
    deps: Mapping[str, DepResult | tuple[DepResult, ...]]
    out: Path                      # the job's artifact folder (empty, writable)
    cache: Path                    # a store-wide scratch folder for caches shared between jobs
    log: logging.Logger
    inputs: Mapping[str, Path] = field(default_factory=dict)  # user files by role (content in the key)
    spec: Any = None               # the params validated by the kind's params model (set before the handler runs)
    _progress: ProgressFn = field(default=lambda **_: None, repr=False)

    def progress(self, completed: float, total: float | None = None, description: str | None = None) -> None:
        """Report progress inside the job (shown as a bar under the run's overall bar)."""
        self._progress(completed=completed, total=total, description=description)

    def dep(self, role: str) -> DepResult:
        value = self.deps[role]
        if isinstance(value, tuple):
            raise MatrixError(f"dependency {role!r} of {self.name} is a group; use ctx.deps[{role!r}]")
        return value

    def dep_group(self, role: str) -> tuple[DepResult, ...]:
        value = self.deps[role]
        return value if isinstance(value, tuple) else (value,)


Handler = Callable[[JobContext], Mapping[str, Any]]
CodeSources = Iterable[str | ModuleType | Callable | type]   # module names, or what a module defines


@dataclass(frozen=True, eq=False)
class JobKind:
    """A job kind: its typed params, its handler and the code behind it.

    `target` is "package.module:function" (imported only when a job runs, so the handler's module may
    import heavy libraries at its top) or the function itself. `params`, a pydantic model, is the one
    home of the kind's parameters and defaults: jobs are planned with it and the handler reads
    `ctx.spec`, the validated instance. The kind's code is the import closure of the handler's module
    within its top-level package (and the params model's), computed from the source; `code` adds what
    no import names (data files, modules loaded by name), `code_for` the per-job part (the module of
    the one strategy an optimize job applies), and modules in `code_exclude` are left to `code_for`.
    """
    name: str
    target: str | Handler
    params: Any = None
    code: tuple = ()
    code_for: Callable[[Mapping[str, Any]], CodeSources] | None = None
    code_exclude: Callable[[], Iterable[str]] | None = None
    exclusive: bool = False        # run alone (timing jobs): nothing else runs beside it
    resources: Mapping[str, float] = field(default_factory=dict)  # e.g. {"GPU": 1} for Dask placement
    resources_for: Callable[[Mapping[str, Any]], Mapping[str, float]] | None = None  # per job
    exclusive_for: Callable[[Mapping[str, Any]], bool] | None = None  # per job, instead of `exclusive`
    # Seconds a job of this kind typically takes, for a store that has not run it yet (as Dask's default
    # task durations): the scheduler's and the time left's first guess, never part of a key.
    typical_s: float | None = None
    typical_for: Callable[[Mapping[str, Any]], float] | None = None   # per job, instead of `typical_s`
    # Keys of a result's value (at any depth) that say how the run went, not what it made (wall-clock
    # seconds): outside its outputs token, so a rerun (--force) that made the same outputs leaves the jobs
    # that stand on it fresh
    measured: tuple[str, ...] = ()
    # A few words the plan shows beside a job (what its params make of it: "tolerance search"), never in a key
    note_for: Callable[[Mapping[str, Any]], str | None] | None = None

    def runs_alone(self, params: Mapping[str, Any]) -> bool:
        """Whether a job with `params` must have its host to itself (it measures time there)."""
        return bool(self.exclusive_for(params)) if self.exclusive_for is not None else self.exclusive

    def typical(self, params: Mapping[str, Any]) -> float | None:
        """Seconds a job with `params` typically takes (None: the kind does not say)."""
        if self.typical_for is None:
            return self.typical_s
        seconds = self.typical_for(params)
        return None if seconds is None else float(seconds)

    def note(self, params: Mapping[str, Any]) -> str:
        """What the plan says of a job with `params` beside its state ('' when nothing; a note that trips
        on odd params is left out: it never stops a plan)."""
        if self.note_for is None:
            return ""
        try:
            return self.note_for(params) or ""
        except Exception:
            return ""

    @property
    def module(self) -> str:
        return self.target.partition(":")[0] if isinstance(self.target, str) else self.target.__module__

    @cached_property
    def function(self) -> Handler:
        if not isinstance(self.target, str):
            return self.target
        module, _, attribute = self.target.partition(":")
        return getattr(importlib.import_module(module), attribute)

    def handler(self, ctx: JobContext) -> Mapping[str, Any]:
        """Validate the job's params into `ctx.spec`, then run the handler."""
        ctx.spec = self.validate(ctx.params, ctx.name)
        return self.function(ctx)

    def validate(self, params: Mapping[str, Any], where: str = "") -> Any:
        """The params as the kind's model (unknown names and bad values are errors), or None."""
        if self.params is None:
            return None
        if hasattr(self.params, "from_job_params"):   # the domain words its own errors
            return self.params.from_job_params(dict(params), where or self.name)
        try:
            return self.params.model_validate(dict(params))
        except pydantic.ValidationError as error:
            raise MatrixError(f"{where or self.name}: {params_problem(error, self.params)}") from None

    def base_modules(self) -> tuple[str, ...]:
        """The modules every job of this kind runs: the handler's and the params model's import closures."""
        return _remembered(("closure", self.name), self._closure)

    def _closure(self) -> tuple[str, ...]:
        excluded = tuple(self.code_exclude()) if self.code_exclude else ()
        roots = [self.module] + ([self.params.__module__] if self.params is not None else [])
        found: list[str] = []
        for root in roots:
            found += module_closure(root, root.partition(".")[0], exclude=excluded)
        return tuple(dict.fromkeys(found))

    def fingerprint(self, params: Mapping[str, Any], params_json: str | None = None) -> str:
        """The code fingerprint of a job with `params` (given `params_json`, their canonical JSON, the
        per-job part is asked once per distinct params, not once per job)."""
        if self.code_for is None:
            extra = ()
        elif params_json is None:
            extra = tuple(map(str, self.code_for(params)))
        else:
            extra = _remembered(("code_for", self.name, params_json), lambda: tuple(map(str, self.code_for(params))))
        return _remembered(("code", self.name, extra),
                           lambda: closure_fingerprint(self.base_modules() + extra, self.code))


_REMEMBERED: dict[tuple, Any] = {}


def _remembered(key: tuple, compute: Callable[[], Any]) -> Any:
    """Per-kind code facts, computed once per process (until `matrix.fingerprint.clear_caches`)."""
    key = (cache_generation(),) + key
    if key not in _REMEMBERED:
        _REMEMBERED[key] = compute()
    return _REMEMBERED[key]


def params_problem(error: pydantic.ValidationError, model: Any) -> str:
    """One line for a params model's complaint: the key path, what is wrong, did you mean."""
    first = min(error.errors(include_url=False), key=lambda e: e["type"] != "extra_forbidden")
    path = ".".join(map(str, first["loc"])) or "params"
    if first["type"] == "extra_forbidden":
        known = _fields_at(model, first["loc"][:-1])
        return (f"unknown param {path!r}{did_you_mean(str(first['loc'][-1]), known)}; "
                f"known: {', '.join(known) or '(none)'}")
    return f"{path}: {first['msg'].removeprefix('Value error, ')} (got {first.get('input')!r:.80})"


def _fields_at(model: Any, loc: tuple) -> list[str]:
    """The field names of the (nested) model at `loc`, where it can be told."""
    for part in loc:
        info = getattr(model, "model_fields", {}).get(part)
        model = info.annotation if info is not None else None
    return sorted(getattr(model, "model_fields", {}))


KINDS: Registry[JobKind] = Registry("job kind")


def register_kind(name: str, target: str | Handler, *, params: Any = None, code: CodeSources = (),
                  code_for=None, code_exclude=None, exclusive: bool = False,
                  resources: Mapping[str, float] | None = None, resources_for=None, exclusive_for=None,
                  typical_s: float | None = None, typical_for=None, measured: Iterable[str] = ()) -> JobKind:
    """Register job kind `name`, run by `target` ("module:function", or the function)."""
    _check_typical(name, typical_s)
    return KINDS.add(name, JobKind(name, target, params, tuple(code), code_for, code_exclude, exclusive,
                                   dict(resources or {}), resources_for, exclusive_for, typical_s, typical_for,
                                   tuple(measured)))


def guess_kind(name: str, *, typical_s: float | None = None, typical_for=None) -> JobKind:
    """Give registered kind `name` what its jobs typically take (as register_kind's `typical_s` and
    `typical_for`), from a module apart from its code: a guess is never in a key, and written in a
    module no handler or params model imports, tuning it makes no job stale."""
    _check_typical(name, typical_s)
    return KINDS.replace(name, replace(KINDS.get(name), typical_s=typical_s, typical_for=typical_for))


def measured_keys(name: str, *keys: str) -> JobKind:
    """Tell registered kind `name` which keys of its results measure how the run went (as register_kind's
    `measured`), from a module apart from its code, as `guess_kind`: they change nothing a job makes."""
    return KINDS.replace(name, replace(KINDS.get(name), measured=tuple(keys)))


def note_kind(name: str, note_for: Callable[[Mapping[str, Any]], str | None]) -> JobKind:
    """Give registered kind `name` the note the plan shows beside its jobs, from a module apart from its
    code (as `guess_kind`: a note is never in a key)."""
    return KINDS.replace(name, replace(KINDS.get(name), note_for=note_for))


def job_note(job) -> str:
    """What the job's kind says of it in a plan (JobKind.note); '' for a kind not registered here."""
    return KINDS.get(job.kind).note(job.params) if job.kind in KINDS else ""


def _check_typical(name: str, typical_s: float | None) -> None:
    if typical_s is not None and (not isinstance(typical_s, (int, float)) or isinstance(typical_s, bool)
                                  or not 0 < typical_s < float("inf")):
        raise MatrixError(f"job kind {name!r}: typical_s must be a positive number of seconds (got {typical_s!r})")


def job_kind(name: str, **options) -> Callable[[Handler], Handler]:
    """Decorator form of `register_kind`, for a handler defined beside its registration."""
    def decorate(handler: Handler) -> Handler:
        register_kind(name, handler, **options)
        return handler
    return decorate
