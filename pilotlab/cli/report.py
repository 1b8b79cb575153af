"""`pilotlab report RECIPE`: write the recipe's report from whatever results the store holds."""
from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser("report", help="write reports/<recipe>/ from the job store (runs nothing)",
                                   description="Write README.md, index.html, results.csv/json and plots "
                                               "for a recipe from the results in the job store. Cells that "
                                               "have not run are shown as such; a store holding none of "
                                               "the recipe's results is an error (nothing is written).")
    parser.add_argument("recipe")
    parser.add_argument("--store", help="job store folder (default: $PILOTLAB_STORE, else .pilotlab)")
    parser.set_defaults(func=run)


CELL_KINDS = ("offline", "online")   # the jobs a report's rows show


def run(args) -> int:
    from matrix.engine import make_plan, open_store
    from matrix.recipe import load_recipe
    from matrix.stale import FRESH
    from pilotlab.domain import DOMAIN
    from pilotlab.errors import PilotlabError
    from pilotlab.report.recipe import write_recipe_report
    recipe, store = load_recipe(args.recipe, DOMAIN), open_store(DOMAIN, args.store)
    statuses = make_plan(recipe, DOMAIN, store).statuses
    # a cell's rows are its offline job and laps: a recording another recipe shares is no result of this one
    shown = any(status.state == FRESH for status in statuses if status.job.kind in CELL_KINDS)
    if not shown and not any(store.failure(status.job.key) for status in statuses):
        raise PilotlabError(f"the store {store.root} holds no result of the cells of recipe {recipe.name!r}, so the "
                            f"report would show nothing; run `pilotlab run {args.recipe}` first, or give the right --store")
    folder = write_recipe_report(recipe, store, [status.job for status in statuses], force=True)
    print(f"report written: {folder / 'README.md'} and {folder / 'index.html'}")
    return 0
