"""The driving domain as the engine sees it: recipe sections, axes, the planner (pilotlab.planning)
and what follows a run (the report)."""
from __future__ import annotations

from matrix.recipe import Domain, Recipe
from pilotlab.planning import plan
from pilotlab.recipe import SECTIONS
from pilotlab.specs import KIND_MODULES

AXES = ("model", "strategy", "hardware", "circuit", "world")


# --- axes: which names a combination may carry -------------------------------------------------

def _models(config) -> list[str]:
    return list(config.models)


def _strategies(config) -> list[str]:
    from pilotlab.strategies import STRATEGIES
    return sorted(set(STRATEGIES.names()) | set(config.strategies))


def _hardware(config) -> list[str]:
    from pilotlab.hardware import BUILTIN
    return sorted(set(BUILTIN) | set(config.hardware))


def _circuits(config) -> list[str]:
    from pilotlab.circuits import all_circuit_names
    return sorted(set(all_circuit_names()) | set(config.circuits))


def after_run(recipe: Recipe, plan, summary, store) -> None:
    """After `run`: refresh the report from the plan that ran (it is not planned again)."""
    from pilotlab.report.recipe import report_folder, write_recipe_report
    written = write_recipe_report(recipe, store, [status.job for status in plan.statuses], force=False)
    readme = report_folder(recipe) / "README.md"
    print(f"report: {readme} and index.html" if written else f"report unchanged: {readme}")


DOMAIN = Domain(
    name="pilotlab",
    sections=SECTIONS,
    # worlds are checked when planned: their names depend on the assets folder, relative to the recipe
    axes={"model": _models, "strategy": _strategies, "hardware": _hardware, "circuit": _circuits,
          "world": lambda config: None},
    plan=plan,
    kind_modules=KIND_MODULES,
    store_env="PILOTLAB_STORE",
    default_store=".pilotlab",
    after_run=after_run,
)
