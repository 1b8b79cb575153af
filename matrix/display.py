"""What matrix prints for a person, with rich: the plan's table, `status` and `show`, and what a person
sees while a run goes: an overall bar (jobs done / total, time elapsed, time left),
a line per running job with its own progress, and one line per finished job. When the output is not
a terminal (CI, nohup, a notebook), a status line is printed at a steady interval instead of bars.

Time left is estimated from how long each job (or failing that, each job kind) took before on this
store (kept in `<store>/stats.json`), corrected by the jobs of each kind that finish in this run, by
the running jobs' own progress and by how many jobs ran at once, and smoothed, so it counts down
instead of jumping.

The commands (matrix.cli) import this module when they print for a person: rich takes ~0.03 s to
import, which `plan --json` and scripts reading it need not pay.
"""
from __future__ import annotations

import json
import os
import sys
import threading
import time
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskID, TextColumn
from rich.table import Table

from matrix.errors import MatrixError
from matrix.kinds import job_note
from matrix.runs import RunSummary
from matrix.store import ARTIFACTS, LOG, RUNS_LOCK, Store
from matrix.times import KindStats, kind_times, recipe_keys, recipe_records

SYMBOLS = {"ok": "[green]✓[/]", "not_applicable": "[yellow]–[/]", "failed": "[red]✗[/]",
           "skipped": "[red]↷[/]", "not_started": "[red]·[/]", "done_elsewhere": "[green]✓[/]", "kept": "[green]✓[/]"}
KNOWN_WEIGHT = 3          # the store's estimate of a kind counts as this many of this run's finished jobs
NAME_WIDTH = 44           # longer job names are cut, so the times stay on the line
PLAIN_INTERVAL_S = 10.0   # a status line this often when the output is not a terminal
SMOOTHING = 0.2           # weight of a new estimate against the shown one, per update
STATE_STYLE = {"fresh": "green", "stale": "yellow", "new": "cyan"}
PLAN_ROWS = 50   # a plan with more jobs than this is summarised per kind, then its first rows


def print_plan(console: Console, statuses: Sequence, counts: Mapping[str, Counter], every_row: bool = False,
               tool: str = "matrix") -> None:
    """The plan as a table of jobs (status, kind, name, reason, key) and a line of counts. A large plan
    (rich takes about a millisecond a row) gets a table of counts per kind and the first PLAN_ROWS
    jobs that would run instead; `every_row` shows them all (`plan --json` lists them too)."""
    if len(statuses) <= PLAN_ROWS:
        console.print(_jobs_table(statuses))
    elif every_row:   # plain lines: rich's table took 22 s for 40,804 jobs (an outside test), these a fraction of one
        console.file.write(_plain_rows(statuses))
    else:
        console.print(_kinds_table(counts))
        shown = [s for s in statuses if s.state != "fresh"][:PLAN_ROWS] or list(statuses[:PLAN_ROWS])
        console.print(_jobs_table(shown))
        console.print(f"[dim]… the first {len(shown)} of {len(statuses)} jobs; every one: "
                      f"{tool} plan --all, or --json[/]")
    console.print(_counts_line(statuses, counts))


PIPED_WIDTH = 200   # columns of tables written to a pipe or file (rich takes 80: names and reasons wrapped)


def console() -> Console:
    """The console of the CLI's output; written to a pipe or a file (`plan | less`, a CI log) its tables
    are PIPED_WIDTH wide, unless $COLUMNS says otherwise."""
    piped = not sys.stdout.isatty() and not os.environ.get("COLUMNS")
    return Console(highlight=False, soft_wrap=True, width=PIPED_WIDTH if piped else None)


def summary_line(summary: RunSummary, tool: str) -> str:
    counts = summary.counts()
    parts = [f"{n} {status.replace('_', ' ')}" for status, n in sorted(counts.items())]
    verdict = "[red]failed[/]" if summary.failed else "[green]done[/]"
    failed = [o for o in summary.outcomes if o.status == "failed"]
    hint = "" if not failed else "\n" + "\n".join(f"  {tool} show {o.key[:10]}   # {escape(o.name)}: its error and log"
                                                for o in failed[:5])
    return f"{verdict}: {', '.join(parts)}; {summary.fresh} were fresh — {summary.wall_s:.1f} s" + hint


JOB_COLUMNS = ("status", "kind", "job", "reason", "key", "note")   # a plan's jobs, as a table or plain lines


def _jobs_table(statuses: Iterable) -> Table:
    table = Table(*JOB_COLUMNS, box=None, pad_edge=False)
    for s in statuses:
        style = STATE_STYLE[s.state]
        table.add_row(f"[{style}]{s.state}[/]", s.job.kind, escape(s.job.name), escape(s.reason), s.job.key[:10],
                      f"[dim]{escape(job_note(s.job))}[/]")
    return table


def _plain_rows(statuses: Sequence) -> str:
    """The jobs table as aligned plain text, a line a job (no colours: meant for a pager or a file)."""
    rows = [JOB_COLUMNS] + [
        (s.state, s.job.kind, s.job.name, s.reason, s.job.key[:10], job_note(s.job)) for s in statuses]
    widths = [max(len(row[i]) for row in rows) for i in range(5)]
    return "".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths)) + "  " + row[5] + "\n"
                   for row in rows)


def _kinds_table(counts: Mapping[str, Counter]) -> Table:
    table = Table("kind", *STATE_STYLE, "jobs", box=None, pad_edge=False)
    for kind, by_state in counts.items():
        table.add_row(kind, *(f"[{style}]{by_state[state]}[/]" if by_state[state] else "·"
                              for state, style in STATE_STYLE.items()), str(sum(by_state.values())))
    return table


def _counts_line(statuses: Sequence, counts: Mapping[str, Counter]) -> str:
    parts = []
    for kind, by_state in counts.items():
        states = ", ".join(f"{n} {state}" for state, n in sorted(by_state.items()))
        parts.append(f"{kind}: {states}")
    total = Counter(s.state for s in statuses)
    summary = ", ".join(f"{n} {state}" for state, n in sorted(total.items()))
    return f"[bold]{len(statuses)} jobs[/] ({summary}) — " + "; ".join(parts)


class NullDisplay:
    def start(self, jobs: Iterable) -> None: ...
    def job_started(self, job) -> None: ...
    def job_waiting(self, job) -> None: ...
    def job_progress(self, key: str, **update) -> None: ...
    def job_finished(self, outcome) -> None: ...
    def stop(self) -> None: ...


Display = NullDisplay


class Estimate:
    """Seconds left: the prior of each job not finished, the running ones corrected by their own
    progress, divided by how many jobs have been running at once (at most as many as are left);
    smoothed. A job's prior is what it took the last time on this store; failing that its kind's
    estimate (matrix.times.KindStats), which the jobs of the kind that finish in this run correct as
    they go: by how their time compared with their own prior, so that a lap with a tolerance search
    still counts as a dozen plain ones (a kind not measured on this store has only its own jobs to go by)."""

    def __init__(self, stats: KindStats, jobs: Iterable, now: float):
        jobs = list(jobs)
        self.measured = {job.kind for job in jobs if stats.measured(job.kind)}   # before this run adds to them
        self.kind = {job.key: job.kind for job in jobs}
        self.own = {job.key for job in jobs if job.name in stats.names}   # priors of the job itself
        self.prior = {job.key: stats.estimate(job.kind, job.name, getattr(job, "params", None)) for job in jobs}
        self.finished: dict[str, list[float]] = {}   # kind -> [sum of seconds / prior, jobs] of this run
        self.started_at: dict[str, float] = {}
        self.fraction: dict[str, float] = {}
        self.busy_s = 0.0                      # job-seconds of finished jobs
        self.began = now
        self.shown: float | None = None
        self.shown_at = now

    def job_started(self, key: str, now: float) -> None:
        self.started_at[key] = now

    def job_progress(self, key: str, fraction: float) -> None:
        self.fraction[key] = min(max(fraction, 0.0), 1.0)

    def job_finished(self, key: str, now: float, counted: bool = True) -> None:
        """`counted`: whether the job did its work (one that was not applicable, failed or was skipped
        says nothing of how long the others of its kind take)."""
        if key in self.started_at:
            seconds = now - self.started_at.pop(key)
            self.busy_s += seconds
            if counted and key in self.kind and self.prior.get(key, 0) > 0:
                total = self.finished.setdefault(self.kind[key], [0.0, 0])
                total[0], total[1] = total[0] + seconds / self.prior[key], total[1] + 1
        self.prior.pop(key, None)
        self.fraction.pop(key, None)

    def raw(self, now: float) -> float:
        factors = {kind: self._kind_factor(kind) for kind in self.finished}
        work = sum(self._left_of(key, now, factors) for key in self.prior)
        running = sum(now - at for at in self.started_at.values())
        parallel = max(1.0, (self.busy_s + running) / max(now - self.began, 1e-9))
        # bounded by the jobs left, not by the jobs running now: while a training runs alone, the twenty
        # jobs after it still run as many at once as the run has so far (the quickstart's time left read
        # 1.6-2x what was left, all of its training long)
        return work / min(parallel, max(1, len(self.prior)))

    def left(self, now: float) -> float:
        """The shown estimate: it counts down with the clock and moves a share towards the raw one."""
        raw = self.raw(now)
        if self.shown is None or not self.prior:     # nothing left: say so at once
            self.shown = raw
        else:
            counted_down = max(0.0, self.shown - (now - self.shown_at))
            self.shown = counted_down + SMOOTHING * (raw - counted_down)
        self.shown_at = now
        return self.shown

    def _kind_factor(self, kind: str) -> float:
        """How much longer than their priors the kind's jobs took in this run (the store's estimate
        counts as KNOWN_WEIGHT jobs that took their prior; for a kind not measured here this run's jobs
        are all there is)."""
        ratios, count = self.finished[kind]
        weight = KNOWN_WEIGHT if kind in self.measured else 0
        return (weight + ratios) / (weight + count)

    def _left_of(self, key: str, now: float, factors: Mapping[str, float]) -> float:
        prior = self.prior[key]
        if key not in self.own:
            prior *= factors.get(self.kind.get(key, ""), 1.0)
        if key not in self.started_at:
            return prior
        elapsed, done = now - self.started_at[key], self.fraction.get(key, 0.0)
        from_prior = max(prior - elapsed, 0.1 * prior)
        if done < 0.05:
            return from_prior
        from_progress = elapsed * (1 - done) / done
        return done * from_progress + (1 - done) * from_prior   # trust the job's progress as it grows


def clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def short(name: str, width: int = NAME_WIDTH) -> str:
    return name if len(name) <= width else name[:width - 1] + "…"


class RichDisplay(NullDisplay):
    def __init__(self, store: Store, console: Console | None = None, title: str = "jobs",
                 interval_s: float = PLAIN_INTERVAL_S):
        self.console = console or Console(stderr=True)
        self.live = self.console.is_terminal
        self.stats = KindStats(store)
        self.title = title
        self.interval_s = interval_s if not self.live else 1.0
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(bar_width=24),
                                 TextColumn("{task.fields[count]}"), TextColumn("[dim]{task.fields[times]}"),
                                 console=self.console, transient=False)
        self.tasks: dict[str, TaskID] = {}
        self.running: dict[str, tuple[str, float, str]] = {}    # key -> (name, started, what)
        self.weights: dict[str, float] = {}
        self.done = self.total = 0
        self.lock = threading.Lock()
        self.stopped = threading.Event()

    def start(self, jobs: Iterable) -> None:
        jobs = list(jobs)
        now = time.monotonic()
        self.total, self.began = len(jobs), now
        self.estimate = Estimate(self.stats, jobs, now)
        self.params = {job.key: getattr(job, "params", None) for job in jobs}   # how the kind's guess compared
        self.weights = dict(self.estimate.prior)      # each job's share of the bar: its prior, priced once
        self.overall = self.progress.add_task(f"[bold]{short(self.title, 24)}", total=sum(self.weights.values()) or 1,
                                              count=f"0/{self.total}", times=self._times(now))
        if self.live:
            self.progress.start()
        self.ticker = threading.Thread(target=self._tick, name="matrix-display", daemon=True)
        self.ticker.start()

    def job_started(self, job) -> None:
        with self.lock:
            now = time.monotonic()
            self.estimate.job_started(job.key, now)
            self.running[job.key] = (job.name, now, "")
            self.tasks[job.key] = self.progress.add_task(f"  {escape(short(job.name))}", total=None, count="",
                                                         times="")

    def job_waiting(self, job) -> None:
        with self.lock:
            self.running.pop(job.key, None)
            self.estimate.started_at.pop(job.key, None)
            self._remove(job.key)

    def job_progress(self, key: str, completed=None, total=None, description=None) -> None:
        with self.lock:
            if key not in self.tasks:
                return
            if completed is not None and total:
                self.estimate.job_progress(key, completed / total)
            fields = {"completed": completed, "total": total}
            if description:
                fields["count"] = escape(short(description, 30))
                name, started, _ = self.running[key]
                self.running[key] = (name, started, description)
            self.progress.update(self.tasks[key], **{k: v for k, v in fields.items() if v is not None})

    def job_finished(self, outcome) -> None:
        with self.lock:
            self._remove(outcome.key)
            self.running.pop(outcome.key, None)
            self.estimate.job_finished(outcome.key, time.monotonic(), counted=outcome.status == "ok")
            self.done += 1
            self.progress.update(self.overall, advance=self.weights.get(outcome.key, 0),
                                 count=f"{self.done}/{self.total}", times=self._times(time.monotonic()))
        if outcome.status == "ok":
            self.stats.add(outcome.kind, outcome.duration_s, outcome.name, self.params.get(outcome.key))
        reason = f" [dim]{escape(outcome.reason)}[/]" if outcome.reason else ""
        took = f" [dim]{outcome.duration_s:.1f}s[/]" if outcome.duration_s else ""
        self.progress.console.print(f"{SYMBOLS.get(outcome.status, '?')} {escape(outcome.name)}{took}{reason}",
                                    highlight=False, soft_wrap=True)

    def stop(self) -> None:
        self.stopped.set()
        if self.live:
            self.progress.stop()
        self.stats.save()

    def status_line(self, now: float) -> str:
        """One line for a log: jobs done, the times, and what runs (with its own progress)."""
        jobs = [f"{short(name)} {clock(now - started)}" + (f" ({short(what, 30)})" if what else "")
                for name, started, what in self.running.values()]
        running = f"; running: {', '.join(jobs)}" if jobs else ""
        return f"{self.done}/{self.total} jobs, {self._times(now)}{running}"

    def _times(self, now: float) -> str:
        left = self.estimate.left(now)
        return f"elapsed {clock(now - self.began)}, about {clock(left)} left"

    def _tick(self) -> None:
        while not self.stopped.wait(self.interval_s):
            with self.lock:
                now = time.monotonic()
                if self.live:
                    self.progress.update(self.overall, times=self._times(now))
                    for key, task in self.tasks.items():
                        self.progress.update(task, times=f"elapsed {clock(now - self.running[key][1])}")
                    continue
                line = self.status_line(now)
            self.console.print(escape(line), highlight=False, soft_wrap=True)

    def _remove(self, key: str) -> None:
        if key in self.tasks:
            self.progress.remove_task(self.tasks.pop(key))


# --- what `status` and `show` print -------------------------------------------------------------------

def print_status(out: Console, store: Store) -> int:
    """`status`: the stored jobs per kind and status, failures, running jobs, recipes run."""
    out.print(f"store: {store.root.resolve()}")
    kinds: dict[str, Counter] = {}
    stored = list(store.keys())
    for key in stored:
        spec, result = store.spec(key) or {}, store.result(key)
        intact = result is not None and store.outputs_intact(key, result)   # files as recorded (by stat, else sha256)
        kinds.setdefault(spec.get("kind", "?"), Counter())[result["status"] if intact else "corrupt"] += 1
    table = Table("kind", "ok", "not applicable", "corrupt (a run rebuilds it)", box=None)
    for kind, counts in sorted(kinds.items()):
        table.add_row(kind, str(counts["ok"]), str(counts["not_applicable"]), str(counts["corrupt"]))
    out.print(table if kinds else "no finished jobs yet")
    failed = sorted((store.root / "failed").glob("*.json"))
    running = [p.stem for p in (store.root / "locks").glob("*.lock") if p.name != RUNS_LOCK and store.is_locked(p.stem)]
    # a failure is rerun by the next run of a recipe that reaches it; one no recipe reaches any more, gc removes
    out.print(f"failed: {len(failed)}{_named(store, failed)} (a run of a recipe that reaches one reruns it; gc removes "
              f"those none reaches); running now: {len(running)}")
    stored = set(stored)
    for record in recipe_records(store):
        missing = sum(1 for key in record.keys if key not in stored)
        gone = f", {missing} of them not stored now (removed since, or not run yet)" if missing else ""
        out.print(f"recipe {escape(record.name)}: {len(record.keys)} jobs ({escape(record.file)}){gone}")
    return 0


SHOWN_FAILED = 3


def _named(store: Store, failed: list[Path]) -> str:
    """The failed jobs by name (the first few): the count alone did not say which."""
    names = [((store.failure(p.stem) or {}).get("spec") or {}).get("name") or p.stem[:12] for p in failed]
    if not names:
        return ""
    more = f" and {len(names) - SHOWN_FAILED} more" if len(names) > SHOWN_FAILED else ""
    return ": " + ", ".join(escape(str(name)) for name in names[:SHOWN_FAILED]) + more


def print_times(out: Console, store: Store, recipe: str | None) -> int:
    """`status --times`: how long the stored jobs took, per kind."""
    keys = None if recipe is None else recipe_keys(store, recipe)
    if recipe is not None and keys is None:
        raise MatrixError(f"recipe {recipe!r} never ran on the store {store.root}; give the file or `name:` of a recipe "
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


def print_job(out: Console, store: Store, key: str) -> int:
    """`show`: one stored job's spec, result, log and artifacts."""
    spec = store.spec(key) or (store.failure(key) or {}).get("spec", {})
    result, failure = store.result(key), store.failure(key)
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
    elif store.job_dir(key).is_dir():   # a folder without a readable result (said nothing: outside test)
        out.print(f"status: [red]stored result missing or corrupt[/] ({store.job_dir(key) / 'result.json'}): "
                  "the next run of a recipe that reaches it runs it again")
    if failure is not None:
        out.print(f"[red]failed last time:[/] {escape(failure.get('error', ''))}")
        out.print(escape(failure.get("traceback", "")))
    return 0
