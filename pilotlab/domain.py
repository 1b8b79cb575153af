"""The driving domain as the engine sees it: recipe sections, axes, the planner (pilotlab.planning)
and what follows a run (the report)."""
from __future__ import annotations

import json
from pathlib import Path

from matrix.errors import MatrixError
from matrix.recipe import Domain, Recipe, declared_values
from pilotlab.planning import plan
from pilotlab.recipe import SECTIONS
from pilotlab.specs import KIND_MODULES

AXES = ("model", "strategy", "hardware", "circuit", "world")


# --- axes: which names a combination may carry -------------------------------------------------

def _models(recipe: Recipe) -> list[str]:
    return list(recipe.config.models)


def _strategies(recipe: Recipe) -> list[str]:
    from pilotlab.strategies import STRATEGIES
    return sorted(set(STRATEGIES.names()) | set(recipe.config.strategies))


def _hardware(recipe: Recipe) -> list[str]:
    from pilotlab.hardware import BUILTIN
    return sorted(set(BUILTIN) | set(recipe.config.hardware))


def _circuits(recipe: Recipe) -> list[str]:
    """Circuit names, and the paths the matrix writes (the planner says which name no file, and where it looked)."""
    from pilotlab.circuits import all_circuit_names
    from pilotlab.circuits.lookup import names_a_path
    folder = Path(recipe.file).resolve().parent
    paths = {value for _, axis, value in declared_values(recipe.config.matrix) if axis == "circuit" and
             isinstance(value, str) and names_a_path(value)}
    return sorted(set(all_circuit_names(folder)) | set(recipe.config.circuits) | paths)


def same_definition(config, axis: str, value) -> tuple | None:
    """What makes a model or strategy name plan the same jobs as another: its definition (its name goes into
    no job's params), so 1000 names of one model are planned once (matrix.grid). None (plan it as itself)
    for other axes, and where a hardware profile's latency file is looked up by model and strategy name."""
    if axis not in ("model", "strategy") or not isinstance(value, str) or \
            any(profile.latency_file is not None for profile in config.hardware.values()):
        return None
    if axis == "model":
        spec = config.models.get(value)
        return None if spec is None else ("model", spec.model_dump_json())
    options = dict(config.strategies.get(value, {}))
    base = options.pop("use", value)
    if not isinstance(base, str):
        return None
    try:   # keyed as its jobs are, defaults filled in (a name in error plans as itself, and is told)
        from pilotlab.strategies import full_options
        options = full_options(base, options)
    except MatrixError:
        return None
    return ("strategy", base, json.dumps(options, sort_keys=True, default=repr))


def planned_on_another_host(spec: dict) -> str | None:
    """gc: a timing or lap planned on another machine sharing the store (or this one with other cores: a
    cpuset, a Slurm allocation) is not this plan's to remove; gc on that host decides."""
    host = (spec.get("params") or {}).get("host")
    if not isinstance(host, dict):
        return None
    from pilotlab.hardware import describe_host, host_fingerprint   # (its parts are cached there)
    return None if host == host_fingerprint() else f"planned for another host ({describe_host(host)})"


def after_run(recipe: Recipe, plan, summary, store) -> None:
    """After `run`: refresh the report from the plan that ran (it is not planned again)."""
    from pilotlab.report.recipe import report_folder, write_recipe_report
    written = write_recipe_report(recipe, store, [status.job for status in plan.statuses], force=False)
    readme = report_folder(recipe) / "README.md"
    print(f"report: {readme} and index.html" if written else f"report unchanged: {readme}")
    if line := unstable_line(recipe, plan, store):
        print(line)


def unstable_line(recipe: Recipe, plan, store) -> str | None:
    """What the run's terminal says of timings that stayed disturbed (the report marks them ⚠ and draws
    nothing from them): how many, and how to measure them again; None when there are none."""
    from pilotlab.specs.online import timed_live
    timed = [status.job for status in plan.statuses if status.job.kind == "timing" or
             status.job.kind == "online" and timed_live(status.job.params)]
    disturbed = [job for job in timed if ((store.result(job.key) or {}).get("value") or {}).get("unstable")]
    if not disturbed:
        return None
    kinds = sorted({job.kind for job in disturbed})
    again = " ".join(f"--force {kind}" for kind in kinds)
    # not "other processes used the cores": a timing on a Dask worker was disturbed by the worker's own threads
    return (f"⚠ {len(disturbed)} of {len(timed)} timings stayed disturbed (the machine was busy while they were "
            f"measured): the report marks them, with each one's reason, and draws no conclusion from them; on a "
            f"quiet machine, `pilotlab run {recipe.file} {again}` measures them again")


DOMAIN = Domain(
    name="pilotlab",
    sections=SECTIONS,
    # worlds are checked when planned: their names depend on the assets folder, relative to the recipe
    axes={"model": _models, "strategy": _strategies, "hardware": _hardware, "circuit": _circuits,
          "world": lambda recipe: None},
    plan=plan,
    kind_modules=KIND_MODULES,
    store_env="PILOTLAB_STORE",
    default_store=".pilotlab",
    after_run=after_run,
    same=same_definition,
    kept_elsewhere=planned_on_another_host,
)
