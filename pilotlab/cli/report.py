"""`pilotlab report RECIPE`: write the recipe's report from whatever results the store holds."""
from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser("report", help="write reports/<recipe>/ from the job store (runs nothing)",
                                   description="Write README.md, index.html, results.csv/json and plots "
                                               "for a recipe from the results in the job store. Cells that "
                                               "have not run are shown as such.")
    parser.add_argument("recipe")
    parser.add_argument("--store", help="job store folder (default: $PILOTLAB_STORE, else .pilotlab)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from matrix.engine import open_store
    from matrix.recipe import load_recipe
    from pilotlab.domain import DOMAIN
    from pilotlab.report.recipe import write_recipe_report
    recipe = load_recipe(args.recipe, DOMAIN)
    folder = write_recipe_report(recipe, open_store(DOMAIN, args.store), DOMAIN, force=True)
    print(f"report written: {folder / 'README.md'} and {folder / 'index.html'}")
    return 0
