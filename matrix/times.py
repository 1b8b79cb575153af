"""Where a recipe's minutes go: the stored jobs' durations, summed per kind.

    rows = kind_times(store, recipe="quickstart")    # [KindTime(kind, jobs, total_s, mean_s, max_s, slowest)]

Durations are what each job took when it ran (`duration_s` in its result), so a table read after a
cold run says how long each kind of work took; jobs run at once overlap, so the sum over kinds can
exceed the run's wall time (`run` prints that).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from matrix.store import Store, read_json


@dataclass(frozen=True)
class KindTime:
    kind: str
    jobs: int
    total_s: float
    max_s: float
    slowest: str          # the name of the longest job of the kind

    @property
    def mean_s(self) -> float:
        return self.total_s / self.jobs if self.jobs else 0.0


def recipe_keys(store: Store, recipe: str) -> list[str] | None:
    """The keys of the jobs of `recipe`'s last run or plan on this store (None if it never ran here)."""
    from matrix.engine import slug
    index = read_json(store.recipe_path(slug(recipe)))
    if not isinstance(index, dict):
        return None
    return [spec["key"] for spec in index.get("jobs", {}).values()]


def kind_times(store: Store, keys: Iterable[str] | None = None) -> list[KindTime]:
    """Per kind, the finished jobs among `keys` (default: every stored job), slowest kind first."""
    totals: dict[str, list] = {}
    for key in store.keys() if keys is None else keys:
        spec, result = store.spec(key), store.result(key)
        if not spec or not result:
            continue
        seconds = float(result.get("duration_s") or 0.0)
        entry = totals.setdefault(spec.get("kind", "?"), [0, 0.0, -1.0, ""])
        entry[0] += 1
        entry[1] += seconds
        if seconds > entry[2]:
            entry[2], entry[3] = seconds, spec.get("name", key[:10])
    rows = [KindTime(kind, jobs, total, longest, name) for kind, (jobs, total, longest, name) in totals.items()]
    return sorted(rows, key=lambda row: -row.total_s)
