"""Job kinds: the domain registers a handler per kind; the engine runs it in a worker.

    @job_kind("train", code=["mydomain.training", "mydomain.models"])
    def run_train(ctx: JobContext) -> dict:
        fit = load_trainer()     # heavy libraries: in the handler, not at import, so planning stays quick
        ...                      # read ctx.params, ctx.deps["data"].artifacts, write into ctx.out
        return {"val_mse": 0.01} # JSON-serialisable result

Code is best named by module name: it is fingerprinted from its file without being imported, so
planning (which imports every kind's module) stays quick.

A handler raises `NotApplicable(reason)` when the job cannot run on this hardware: the result is
recorded (and cached) as "not applicable: reason", and jobs that depend on it get the same status
without running.
"""
from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from matrix.errors import MatrixError
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


@dataclass(frozen=True)
class JobKind:
    name: str
    handler: Handler
    # The code whose text makes up this kind's fingerprint: fixed modules, plus per-job extras
    # (for example the module of the one strategy an optimize job applies).
    code: tuple = ()
    code_for: Callable[[Mapping[str, Any]], CodeSources] | None = None
    exclusive: bool = False        # run alone (timing jobs): nothing else runs beside it
    resources: Mapping[str, float] = field(default_factory=dict)  # e.g. {"GPU": 1} for Dask placement
    resources_for: Callable[[Mapping[str, Any]], Mapping[str, float]] | None = None  # per job


KINDS: Registry[JobKind] = Registry("job kind")


def job_kind(name: str, *, code: CodeSources = (), code_for=None, exclusive: bool = False,
             resources: Mapping[str, float] | None = None, resources_for=None) -> Callable[[Handler], Handler]:
    """Register `handler` as the implementation of job kind `name`."""
    def decorate(handler: Handler) -> Handler:
        KINDS.add(name, JobKind(name, handler, tuple(code), code_for, exclusive, dict(resources or {}),
                                resources_for))
        return handler
    return decorate
