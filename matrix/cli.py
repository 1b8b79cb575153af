"""Engine commands for a domain's command line: run, plan, status, show, gc.

    add_engine_commands(subparsers, get_domain)

`get_domain()` is called only when a command runs, so other commands stay quick to start; so is
matrix.display, which prints for a person with rich (~0.03 s to import): `plan --json` needs none.
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

from matrix import engine
from matrix.errors import MatrixError
from matrix.grid import describe_alike
from matrix.kinds import job_note
from matrix.recipe import Domain, load_recipe
from matrix.runs import default_jobs
from matrix.times import recipe_records

GetDomain = Callable[[], Domain]
ENGINE_COMMANDS = ("run", "plan", "status", "show", "gc")   # what add_engine_commands adds


def add_engine_commands(subparsers, get_domain: GetDomain,
                        store_help: str = "job store folder (default: the domain's default)") -> None:

    def add(name: str, func, help: str) -> argparse.ArgumentParser:
        parser = subparsers.add_parser(name, help=help, description=help)
        parser.add_argument("--store", help=store_help)
        parser.set_defaults(func=lambda args: func(args, get_domain()), tool=parser.prog.rsplit(" ", 1)[0])
        return parser

    run = add("run", cmd_run, "run a recipe: every job that is not fresh, in dependency order")
    run.add_argument("recipe")
    run.add_argument("-j", "--jobs", type=int, default=None,
                     help=f"jobs at once (worker processes; default: one per core, {default_jobs()} here); a timing "
                          "job always runs alone")
    run.add_argument("--keep-going", action="store_true", help="after a failure, run what does not depend on it")
    run.add_argument("--force", action="append", default=[], metavar="KIND",
                     help="rerun every job of KIND, and the jobs that stand on them where its outputs change")
    run.add_argument("--executor", choices=["local", "dask", "dask-local"], default="local",
                     help="local process pool (default), a Dask cluster (--scheduler), or a local Dask cluster")
    run.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address, e.g. tcp://host:8786")
    run.add_argument("--timing-resource", metavar="NAME",
                     help="with Dask: run timing jobs only on workers started with --resources NAME=1")
    plan = add("plan", cmd_plan, "show what `run` would do: each job fresh / stale / new, and why")
    plan.add_argument("recipe")
    plan.add_argument("--json", action="store_true", help="print a JSON list of every job instead of a table")
    plan.add_argument("--all", action="store_true",
                      help="a row for every job (by default a large plan shows a summary per kind and its first rows)")
    plan.add_argument("--force", action="append", default=[], metavar="KIND",
                      help="show every job of KIND (and what stands on it) as stale")
    status = add("status", cmd_status, "summarise the job store")
    status.add_argument("--times", action="store_true",
                        help="how long the stored jobs took, per kind (where a recipe's minutes go)")
    status.add_argument("--recipe", metavar="NAME|FILE",
                        help="how long the jobs of this recipe's last run took (its name, or its file)")
    # as `run` and `plan` take it: `status recipes/study.yaml` was refused with "unrecognized arguments"
    status.add_argument("recipe_given", nargs="?", metavar="recipe", help="the same as --recipe")
    show = add("show", cmd_show, "show one stored job: spec, result, log and artifacts")
    show.add_argument("key", help="a job key or its first characters")
    gc = add("gc", cmd_gc, "remove stored jobs that none of the given recipes reaches")
    gc.add_argument("recipes", nargs="+")
    gc.add_argument("--dry-run", action="store_true", help="list what would be removed")
    gc.add_argument("--all-hosts", action="store_true",
                    help="remove what no recipe reaches here even where the domain keeps it for another host "
                         "(a retired machine's timings)")


def cmd_plan(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    plan = engine.make_plan(load_recipe(args.recipe, domain), domain, store, args.force)
    if args.store and not store.root.is_dir():   # a typo more likely than a store to come: say so, plan all the same
        print(f"note: --store {args.store}: no such folder yet, so every job is new (`run` makes it)", file=sys.stderr)
    if args.json:
        rows = [{"key": s.job.key, "kind": s.job.kind, "name": s.job.name, "status": s.state,
                 "reason": s.reason, "note": job_note(s.job)} for s in plan.statuses]
        print(json.dumps(rows, indent=1))
        return 0
    from matrix import display
    out = display.console()
    display.print_plan(out, plan.statuses, plan.counts(), every_row=args.all, tool=args.tool)
    if plan.recipe.grid is not None and (alike := describe_alike(plan.recipe.grid)):
        out.print(display.escape(alike))   # names that define the same thing are planned (and shown) once
    return 0


def cmd_run(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    recipe = load_recipe(args.recipe, domain)
    args.jobs = default_jobs() if args.jobs is None else args.jobs
    executor = engine.Executor(args.executor, args.jobs, args.scheduler, args.timing_resource)
    plan = engine.make_plan(recipe, domain, store, args.force)
    from matrix import display
    out, name = display.console(), display.escape(recipe.name)
    if not plan.stale:
        out.print(f"nothing to do: all {len(plan.statuses)} jobs of {name!s} are fresh")
        summary = engine.run_plan(plan, domain, store, executor=executor)   # runs nothing; records the run
    else:
        where = args.scheduler if args.executor == "dask" else \
            f"{args.jobs} {'Dask ' if args.executor == 'dask-local' else ''}worker{'s' if args.jobs > 1 else ''}"
        out.print(f"{name}: {len(plan.stale)} of {len(plan.statuses)} jobs to run on {where} (store {store.root})")
        summary = engine.run_plan(plan, domain, store, keep_going=args.keep_going,
                                  display=display.RichDisplay(store, title=name), executor=executor)
        out.print(display.summary_line(summary, args.tool))
    if domain.after_run is not None:
        domain.after_run(recipe, plan, summary, store)
    return 1 if summary.failed else 0


def cmd_status(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    if not store.root.is_dir():
        if args.store:   # a folder named that is not there: a typo more likely than a store to come
            raise MatrixError(f"--store {args.store}: no such folder; give the folder a run wrote its jobs to")
        print(f"no job store at {store.root} yet: `run RECIPE` makes it")
        return 0
    from matrix import display
    recipe = _one_recipe(args.recipe, args.recipe_given)
    if args.times or recipe:
        return display.print_times(display.console(), store, _recipe_name(recipe, domain))
    return display.print_status(display.console(), store)


def _one_recipe(option: str | None, positional: str | None) -> str | None:
    if option and positional and option != positional:
        raise MatrixError(f"status: two recipes given ({positional} and --recipe {option}); give one")
    return option or positional


def _recipe_name(given: str | None, domain: Domain) -> str | None:
    """A recipe named by its file (what `run` was given) is the name inside it."""
    return load_recipe(given, domain).name if given and Path(given).is_file() else given


def cmd_show(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    key = store.find(args.key)
    from matrix import display
    return display.print_job(display.console(), store, key)


def cmd_gc(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    recipes = [load_recipe(path, domain) for path in args.recipes]
    keep = {job.key for recipe in recipes for job in engine.plan_jobs(recipe, domain)}
    with store.collecting() as alone:
        if not alone:
            raise MatrixError(f"a run is running on the store {store.root}: gc would remove the jobs it has finished "
                              "and still reads; run gc when it has ended")
        garbage = engine.find_garbage(store, keep, None if args.all_hosts else domain.kept_elsewhere)
        names = {key: _garbage_name(store, key) for key in garbage.keys}
        removed = garbage.keys if args.dry_run else engine.collect_garbage(store, garbage)
    verb = "would remove" if args.dry_run else "removed"
    for key in removed:
        print(f"{verb} {key[:12]} {names[key]}".rstrip())
    kept = sum(1 for key in store.keys() if key in keep)
    print(f"{verb} {len(removed)} jobs and {len(garbage.temp)} leftovers of killed runs "
          f"({garbage.bytes / 1e6:.1f} MB); {'keeping' if args.dry_run else 'kept'} the {kept} stored jobs "
          f"the recipes reach", file=sys.stdout)
    for why, count in Counter(garbage.elsewhere.values()).most_common():
        print(f"{'keeping' if args.dry_run else 'kept'} {count} stored jobs no recipe reaches here: {why} "
              "(gc there collects them, or gc --all-hosts here)")
    for line in _recipes_left_out(store, {recipe.name for recipe in recipes}, set(removed), args.dry_run):
        print(line)
    return 0


def _recipes_left_out(store, given: set[str], removed: set[str], dry_run: bool) -> Iterator[str]:
    """A line for each recipe that ran on this store, was not given, and loses jobs (an outside test lost
    another recipe's work to a gc without a word)."""
    for record in recipe_records(store):
        lost = sum(1 for key in record.keys if key in removed)
        if record.name not in given and lost:
            verb = "would lose" if dry_run else "lost"
            advice = ": give its file too to keep them" if dry_run else \
                " (gc --dry-run says so before removing anything)"
            yield (f"recipe {record.name} ({record.file}), which ran on this store and was not given, {verb} {lost} "
                   f"of its {len(record.keys)} jobs{advice}")


def _garbage_name(store, key: str) -> str:
    """A stored job's kind and name; a failed one's from its failure record."""
    spec = store.spec(key)
    return _kind_and_name(spec) if spec else f"{_kind_and_name((store.failure(key) or {}).get('spec') or {})} (failed)"


def _kind_and_name(spec: dict) -> str:
    kind, name = spec.get("kind", ""), spec.get("name", "")
    return name if name.startswith(f"{kind} ") else f"{kind} {name}".strip()


def main(argv: list[str] | None, domain: Domain, prog: str = "matrix") -> int:
    """A complete command line for a domain with only the engine commands (used by tests)."""
    parser = argparse.ArgumentParser(prog=prog)
    parser.add_argument("-v", "--verbose", action="store_true")
    add_engine_commands(parser.add_subparsers(dest="command", required=True), lambda: domain)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except MatrixError as error:
        if args.verbose:
            raise
        print(f"{prog}: error: {error}", file=sys.stderr)
        return 2
