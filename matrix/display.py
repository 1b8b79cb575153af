"""What a person sees while a run goes: an overall bar (jobs done / total, elapsed, time left), a
line per running job with its own progress, and one line per finished job.

Time left is estimated from how long each job kind took before on this store (kept in
`<store>/stats.json`), so a run of three trainings and a hundred evaluations predicts well.
"""
from __future__ import annotations

from collections.abc import Iterable

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from matrix.store import Store, read_json, write_json_atomic

SYMBOLS = {"ok": "[green]✓[/]", "not_applicable": "[yellow]–[/]", "failed": "[red]✗[/]",
           "skipped": "[red]↷[/]", "not_started": "[red]·[/]", "done_elsewhere": "[green]✓[/]"}
DEFAULT_ESTIMATE_S = 5.0


class NullDisplay:
    def start(self, jobs: Iterable) -> None: ...
    def job_started(self, job) -> None: ...
    def job_waiting(self, job) -> None: ...
    def job_progress(self, key: str, **update) -> None: ...
    def job_finished(self, outcome) -> None: ...
    def stop(self) -> None: ...


Display = NullDisplay


class KindStats:
    """Mean duration per job kind on this store, for time-left estimates."""

    def __init__(self, store: Store):
        self.path = store.root / "stats.json"
        self.means: dict[str, list[float]] = read_json(self.path) or {}

    def estimate(self, kind: str) -> float:
        if kind in self.means:
            return self.means[kind][0]
        known = [mean for mean, _ in self.means.values()]
        return sum(known) / len(known) if known else DEFAULT_ESTIMATE_S

    def add(self, kind: str, seconds: float) -> None:
        mean, count = self.means.get(kind, [0.0, 0])
        count = min(count + 1, 20)  # a moving mean: recent runs matter more
        self.means[kind] = [mean + (seconds - mean) / count, count]

    def save(self) -> None:
        try:
            write_json_atomic(self.path, self.means)
        except OSError:
            pass  # estimates are a nicety; a read-only store still runs


class RichDisplay(NullDisplay):
    def __init__(self, store: Store, console: Console | None = None, title: str = "jobs"):
        self.console = console or Console(stderr=True)
        self.stats = KindStats(store)
        self.title = title
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 TextColumn("{task.fields[count]}"), TimeElapsedColumn(),
                                 TextColumn("left"), TimeRemainingColumn(),
                                 console=self.console, transient=False)
        self.tasks: dict[str, TaskID] = {}
        self.weights: dict[str, float] = {}
        self.done = self.total = 0

    def start(self, jobs: Iterable) -> None:
        jobs = list(jobs)
        self.total = len(jobs)
        self.weights = {job.key: self.stats.estimate(job.kind) for job in jobs}
        self.overall = self.progress.add_task(f"[bold]{self.title}", total=sum(self.weights.values()) or 1,
                                              count=f"0/{self.total}")
        self.progress.start()

    def job_started(self, job) -> None:
        self.tasks[job.key] = self.progress.add_task(f"  {escape(job.name)}", total=None, count="")

    def job_waiting(self, job) -> None:
        self._remove(job.key)

    def job_progress(self, key: str, completed=None, total=None, description=None) -> None:
        if key in self.tasks:
            fields = {"completed": completed, "total": total}
            if description:
                fields["count"] = escape(description)
            self.progress.update(self.tasks[key], **{k: v for k, v in fields.items() if v is not None})

    def job_finished(self, outcome) -> None:
        self._remove(outcome.key)
        self.done += 1
        self.progress.update(self.overall, advance=self.weights.get(outcome.key, 0),
                             count=f"{self.done}/{self.total}")
        if outcome.status == "ok":
            self.stats.add(outcome.kind, outcome.duration_s)
        reason = f" [dim]{escape(outcome.reason)}[/]" if outcome.reason else ""
        took = f" [dim]{outcome.duration_s:.1f}s[/]" if outcome.duration_s else ""
        self.progress.console.print(f"{SYMBOLS.get(outcome.status, '?')} {escape(outcome.name)}{took}{reason}",
                                    highlight=False, soft_wrap=True)

    def stop(self) -> None:
        self.progress.stop()
        self.stats.save()

    def _remove(self, key: str) -> None:
        if key in self.tasks:
            self.progress.remove_task(self.tasks.pop(key))
