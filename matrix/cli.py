"""Engine commands for a domain's command line: run, plan, status, show, gc.

    add_engine_commands(subparsers, get_domain)

`get_domain()` is called only when a command runs, so other commands stay quick to start.
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from collections.abc import Callable

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from matrix import engine
from matrix.display import RichDisplay, print_plan
from matrix.grid import describe_alike
from matrix.recipe import Domain, load_recipe
from matrix.runs import default_jobs
from matrix.store import ARTIFACTS, LOG, Store, read_json

GetDomain = Callable[[], Domain]


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
    run.add_argument("--force", action="append", default=[], metavar="KIND", help="rerun every job of KIND")
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
    plan.add_argument("--force", action="append", default=[], metavar="KIND", help="show every job of KIND as stale")
    status = add("status", cmd_status, "summarise the job store")
    status.add_argument("--times", action="store_true",
                        help="how long the stored jobs took, per kind (where a recipe's minutes go)")
    status.add_argument("--recipe", metavar="NAME", help="with --times: only the jobs of this recipe's last run")
    show = add("show", cmd_show, "show one stored job: spec, result, log and artifacts")
    show.add_argument("key", help="a job key or its first characters")
    gc = add("gc", cmd_gc, "remove stored jobs that none of the given recipes reaches")
    gc.add_argument("recipes", nargs="+")
    gc.add_argument("--dry-run", action="store_true", help="list what would be removed")


def console() -> Console:
    return Console(highlight=False, soft_wrap=True)


def cmd_plan(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    plan = engine.make_plan(load_recipe(args.recipe, domain), domain, store, args.force)
    if args.json:
        rows = [{"key": s.job.key, "kind": s.job.kind, "name": s.job.name, "status": s.state,
                 "reason": s.reason} for s in plan.statuses]
        print(json.dumps(rows, indent=1))
        return 0
    print_plan(console(), plan.statuses, plan.counts(), every_row=args.all, tool=args.tool)
    if plan.recipe.grid is not None and (alike := describe_alike(plan.recipe.grid)):
        console().print(escape(alike))   # names that define the same thing are planned (and shown) once
    return 0


def cmd_run(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    recipe = load_recipe(args.recipe, domain)
    args.jobs = default_jobs() if args.jobs is None else args.jobs
    executor = engine.Executor(args.executor, args.jobs, args.scheduler, args.timing_resource)
    plan = engine.make_plan(recipe, domain, store, args.force)
    out = console()
    if not plan.stale:
        out.print(f"nothing to do: all {len(plan.statuses)} jobs of {escape(recipe.name)!s} are fresh")
        summary = engine.RunSummary(fresh=len(plan.statuses))
    else:
        where = args.scheduler if args.executor == "dask" else \
            f"{args.jobs} {'Dask ' if args.executor == 'dask-local' else ''}worker{'s' if args.jobs > 1 else ''}"
        out.print(f"{escape(recipe.name)}: {len(plan.stale)} of {len(plan.statuses)} jobs to run "
                  f"on {where} (store {store.root})")
        display = RichDisplay(store, title=escape(recipe.name))
        summary = engine.run_plan(plan, domain, store, keep_going=args.keep_going, display=display,
                                  executor=executor)
        out.print(_summary_line(summary, args.tool))
    if domain.after_run is not None:
        domain.after_run(recipe, plan, summary, store)
    return 1 if summary.failed else 0


def _summary_line(summary: engine.RunSummary, tool: str) -> str:
    counts = summary.counts()
    parts = [f"{n} {status.replace('_', ' ')}" for status, n in sorted(counts.items())]
    verdict = "[red]failed[/]" if summary.failed else "[green]done[/]"
    failed = [o for o in summary.outcomes if o.status == "failed"]
    hint = "" if not failed else "\n" + "\n".join(f"  {tool} show {o.key[:10]}   # {escape(o.name)}: its error and log"
                                                for o in failed[:5])
    return f"{verdict}: {', '.join(parts)}; {summary.fresh} were fresh — {summary.wall_s:.1f} s" + hint


def cmd_status(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    out = console()
    if args.times or args.recipe:
        return _print_times(out, store, args.recipe)
    out.print(f"store: {store.root.resolve()}")
    kinds: dict[str, Counter] = {}
    for key in store.keys():
        spec, result = store.spec(key) or {}, store.result(key) or {}
        kinds.setdefault(spec.get("kind", "?"), Counter())[result.get("status", "corrupt")] += 1
    table = Table("kind", "ok", "not applicable", "corrupt", box=None)
    for kind, counts in sorted(kinds.items()):
        table.add_row(kind, str(counts["ok"]), str(counts["not_applicable"]), str(counts["corrupt"]))
    out.print(table if kinds else "no finished jobs yet")
    failed = sorted((store.root / "failed").glob("*.json"))
    running = [p.stem for p in (store.root / "locks").glob("*.lock") if store.is_locked(p.stem)]
    out.print(f"failed (will rerun): {len(failed)}; running now: {len(running)}")
    for index in sorted((store.root / "recipes").glob("*.json")):
        data = read_json(index) or {}
        out.print(f"recipe {escape(data.get('recipe', index.stem))}: {len(data.get('jobs', {}))} jobs "
                  f"({escape(str(data.get('file', '?')))})")
    return 0


def _print_times(out: Console, store: Store, recipe: str | None) -> int:
    from matrix.errors import MatrixError
    from matrix.times import kind_times, recipe_keys
    keys = None if recipe is None else recipe_keys(store, recipe)
    if recipe is not None and keys is None:
        raise MatrixError(f"recipe {recipe!r} never ran on the store {store.root}; give the `name:` of a recipe "
                          "that ran here, or leave --recipe out for every stored job")
    rows = kind_times(store, keys)
    total = sum(row.total_s for row in rows)
    table = Table("kind", "jobs", "total s", "share", "mean s", "max s", "slowest job", box=None)
    for row in rows:
        table.add_row(row.kind, str(row.jobs), f"{row.total_s:.1f}", f"{100 * row.total_s / (total or 1):.0f} %",
                      f"{row.mean_s:.1f}", f"{row.max_s:.1f}", escape(row.slowest))
    out.print(table if rows else "no finished jobs yet")
    what = f"recipe {escape(recipe)}" if recipe else "every stored job"
    out.print(f"{what}: {sum(r.jobs for r in rows)} jobs, {total:.1f} s of job time "
              "(jobs run at once overlap: a run's wall time can be less)")
    return 0


def cmd_show(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    key = store.find(args.key)
    spec = store.spec(key) or (store.failure(key) or {}).get("spec", {})
    result, failure = store.result(key), store.failure(key)
    out = console()
    out.print(f"[bold]{escape(spec.get('name', '?'))}[/] ({spec.get('kind', '?')}) {key}")
    out.print("params: " + escape(json.dumps(spec.get("params", {}), sort_keys=True)))
    for role, dep in spec.get("deps", {}).items():
        names = spec.get("dep_names", {})
        out.print(f"dependency {role}: " + ", ".join(escape(names.get(k, k[:10])) for k in
                                                      (dep if isinstance(dep, list) else [dep])))
    if result is not None:
        out.print(f"status: {result['status']} {escape(result.get('reason', ''))} "
                  f"({result.get('duration_s', 0):.1f} s, {result.get('finished_at', '')})")
        out.print("result: " + escape(json.dumps(result.get("value", {}), indent=1, sort_keys=True)))
        out.print(f"artifacts: {store.job_dir(key) / ARTIFACTS}")
        out.print(f"log: {store.job_dir(key) / LOG}")
    if failure is not None:
        out.print(f"[red]failed last time:[/] {escape(failure.get('error', ''))}")
        out.print(escape(failure.get("traceback", "")))
    return 0


def cmd_gc(args, domain: Domain) -> int:
    store = engine.open_store(domain, args.store)
    keep = {job.key for path in args.recipes for job in engine.plan_jobs(load_recipe(path, domain), domain)}
    garbage = engine.find_garbage(store, keep)
    verb = "would remove" if args.dry_run else "removed"
    for key in garbage.keys:
        spec = store.spec(key) or {}
        print(f"{verb} {key[:12]} {spec.get('kind', '')} {spec.get('name', '')}".rstrip())
    if not args.dry_run:
        engine.collect_garbage(store, garbage)
    kept = sum(1 for key in store.keys() if key in keep)
    print(f"{verb} {len(garbage.keys)} jobs and {len(garbage.temp)} leftovers of killed runs "
          f"({garbage.bytes / 1e6:.1f} MB); {'keeping' if args.dry_run else 'kept'} the {kept} stored jobs "
          f"the recipes reach", file=sys.stdout)
    return 0


def main(argv: list[str] | None, domain: Domain, prog: str = "matrix") -> int:
    """A complete command line for a domain with only the engine commands (used by tests)."""
    from matrix.errors import MatrixError
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
