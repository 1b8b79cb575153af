"""JobContexts built by hand, as the engine would build them."""
from __future__ import annotations

import logging
from pathlib import Path

from matrix.kinds import DepResult, JobContext


def context(tmp_path: Path, kind: str, name: str, params=None, deps=None, inputs=None, progress=None) -> JobContext:
    out = tmp_path / f"{name}-out"
    out.mkdir(parents=True)
    return JobContext(key=f"{name}-key", kind=kind, name=name, params=params or {}, deps=deps or {},
                      inputs=inputs or {}, out=out, cache=tmp_path / "cache", log=logging.getLogger(name),
                      _progress=progress or (lambda **_: None))


def finished(ctx: JobContext, result: dict) -> DepResult:
    """What a job that depends on `ctx`'s job sees of it."""
    return DepResult(key=ctx.key, kind=ctx.kind, params=dict(ctx.params), result=result, artifacts=ctx.out,
                     name=ctx.name)
