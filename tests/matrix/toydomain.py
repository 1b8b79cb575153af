"""A toy domain for engine tests: numbers instead of driving.

    sources:  {a: {value: 2}, b: {value: 3, sleep: 0.2}}
    matrix:   {source: [a, b], power: [2, 3]}

plans one `source` job per source (shared by every power), one `power` job per combination and
one `total` job over all of them; with `measures: true`, also one exclusive `measure` job per power
(a timing job: it notes when and on which host it ran, as the others do, so tests can check that it
ran alone); a source's `worker: NAME` sends its measure jobs to Dask workers declaring resource NAME.
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import sys
import time
from typing import Any, Literal

import pydantic

from matrix import NotApplicable, job_kind
from matrix.hostlock import host_name
from matrix.jobs import Job
from matrix.recipe import Domain, Recipe


class SourceConfig(pydantic.BaseModel):
    model_config = pydantic.ConfigDict(extra="forbid", frozen=True)
    value: int
    sleep: float = 0.0
    fail: bool | Literal["exit"] = False     # exit: call sys.exit(3), as a user's module may
    not_applicable: bool = False
    noise: bool = False           # write to file descriptor 2 directly, as C libraries do
    library_log: bool = False     # log through a handler on sys.stderr made once per process, as torch does
    worker: str | None = None     # the Dask worker resource its measure jobs need (as a hardware profile's)
    jitter: bool = False          # its result also holds a measurement that differs at every run (as a timing)
    took: bool = False            # ... or how long it took ("seconds", declared measured: not an output)


def count_execution(ctx) -> None:
    """Append the job's name to a store-wide file, so tests can count executions across runs."""
    with open(ctx.cache / "executions.log", "a") as log:
        log.write(ctx.name + "\n")


def library_logger() -> logging.Logger:
    """A library's logger whose StreamHandler binds sys.stderr when first made (torch's logging does
    so on import, during whichever job imports torch first)."""
    logger = logging.getLogger("toy.library")
    if not logger.handlers:
        logger.addHandler(logging.StreamHandler())
        logger.propagate = False
    return logger


@contextlib.contextmanager
def timed(ctx):
    """Append "kind key start end host" to the store-wide intervals.log once the job's work is done."""
    started = time.time()
    yield
    with open(ctx.cache / "intervals.log", "a") as log:
        log.write(f"{ctx.kind} {ctx.key} {started:.6f} {time.time():.6f} {host_name()}\n")


@job_kind("source", measured=("seconds",))   # how long it took: a rerun differs there, with the same outputs
def run_source(ctx) -> dict[str, Any]:
    count_execution(ctx)
    if ctx.params["noise"]:
        os.write(2, b"C-level noise\n")
    if ctx.params["library_log"]:
        library_logger().warning("library warning from %s", ctx.name)
    with timed(ctx):
        time.sleep(ctx.params["sleep"])
    if ctx.params["fail"] == "exit":
        sys.exit(3)
    if ctx.params["fail"]:
        raise RuntimeError(f"source {ctx.name} was told to fail")
    if ctx.params["not_applicable"]:
        raise NotApplicable("this source needs hardware we do not have")
    (ctx.out / "value.json").write_text(json.dumps(ctx.params["value"]))
    ctx.progress(1, 1, "written")
    measured = {"measured": time.perf_counter_ns()} if ctx.params["jitter"] else {}
    took = {"seconds": time.perf_counter_ns()} if ctx.params["took"] else {}   # differs at every run
    return {"value": ctx.params["value"], "omp_threads": os.environ.get("OMP_NUM_THREADS"), **measured, **took}


@job_kind("power")
def run_power(ctx) -> dict[str, Any]:
    count_execution(ctx)
    source = ctx.dep("source")
    value = json.loads((source.artifacts / "value.json").read_text())
    with timed(ctx):
        time.sleep(ctx.params.get("sleep", 0.0))
    (ctx.out / "power.txt").write_text(f"{value}^{ctx.params['power']}")
    return {"value": value ** ctx.params["power"]}


@job_kind("measure", exclusive=True, resources_for=lambda params: {params["worker"]: 1} if "worker" in params else {})
def run_measure(ctx) -> dict[str, Any]:
    count_execution(ctx)
    with timed(ctx):
        time.sleep(ctx.params["sleep"])
    return {"value": ctx.dep("power").result["value"] + 1}


@job_kind("total", exclusive=True)
def run_total(ctx) -> dict[str, Any]:
    count_execution(ctx)
    with timed(ctx):
        time.sleep(ctx.params.get("sleep", 0.0))
    return {"value": sum(dep.result["value"] for dep in ctx.dep_group("parts"))}


def plan(recipe: Recipe) -> list[Job]:
    sources = {name: Job("source", f"source {name}", cfg.model_dump(exclude={"worker"}))
               for name, cfg in recipe.config.sources.items()}
    powers = [Job("power", f"power {c['source']}^{c['power']}", {"power": c["power"], "sleep": recipe.config.sleep},
                  deps={"source": sources[c["source"]]}) for c in recipe.combinations]
    workers = [recipe.config.sources[c["source"]].worker for c in recipe.combinations]
    measures = [Job("measure", f"measure {p.name}", {"sleep": recipe.config.sleep} | ({"worker": w} if w else {}),
                    deps={"power": p}) for p, w in zip(powers, workers)] if recipe.config.measures else []
    total = {"sleep": recipe.config.total_sleep} if recipe.config.total_sleep else {}
    return powers + measures + [Job("total", "total", total, deps={"parts": tuple(powers)})]


TOY = Domain(
    name="toy",
    sections={"sources": (dict[str, SourceConfig], ...), "sleep": (float, 0.0), "total_sleep": (float, 0.0),
              "measures": (bool, False)},
    axes={"source": lambda recipe: list(recipe.config.sources), "power": lambda recipe: None},
    plan=plan,
    kind_modules=("tests.matrix.toydomain",),
    store_env="TOY_STORE",
    default_store=".toy",
)
