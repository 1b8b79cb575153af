"""Where a recipe's minutes go: the stored jobs' durations, summed per kind; and how long a job is
expected to take (`KindStats`: what it or its kind took on this store), for the scheduler and the
time left.

    rows = kind_times(store, recipe="quickstart")    # [KindTime(kind, jobs, total_s, mean_s, max_s, slowest)]

Durations are what each job took when it ran (`duration_s` in its result), so a table read after a
cold run says how long each kind of work took; jobs run at once overlap, so the sum over kinds can
exceed the run's wall time (`run` prints that).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from matrix.kinds import KINDS, JobKind
from matrix.store import Store, read_json, write_json_atomic

DEFAULT_ESTIMATE_S = 5.0
# <store>/stats.json: {"format", "kinds": {kind: [mean, n]}, "names": {job name: [mean, n]},
#                      "ratios": {kind: [mean of measured / guessed seconds, n]}}
STATS_FORMAT = 3
MAX_NAMES = 20_000        # job names remembered in stats.json (the least recently run go first)


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
    return _keys_of(index) if isinstance(index, dict) else None


@dataclass(frozen=True)
class RecipeRecord:
    name: str
    file: str
    keys: list[str]       # of its jobs in its last run or plan


def recipe_records(store: Store) -> Iterator[RecipeRecord]:
    """Every recipe that ran (or was planned to run) on this store, from its record under recipes/."""
    for index in sorted((store.root / "recipes").glob("*.json")):
        data = read_json(index)
        data = data if isinstance(data, dict) else {}
        yield RecipeRecord(str(data.get("recipe", index.stem)), str(data.get("file", "?")), _keys_of(data))


def _keys_of(index: dict) -> list[str]:
    jobs = index.get("jobs")
    return [spec["key"] for spec in jobs.values() if isinstance(spec, dict) and "key" in spec] \
        if isinstance(jobs, dict) else []


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


class KindStats:
    """How long jobs took on this store, for time-left estimates: a moving mean per job kind, and per
    job name (a rerun of an edited recipe knows what each of its jobs took the last time); for a kind
    that guesses by params, how far off its guesses were here (this machine's speed, the circuits)."""

    def __init__(self, store: Store):
        self.path = store.root / "stats.json"
        saved = read_json(self.path)
        saved = saved if isinstance(saved, dict) else {}
        if not isinstance(saved.get("format"), int):      # the first format: {kind: [mean, count]}
            saved = {"kinds": saved, "names": {}}
        self.means = _means(saved.get("kinds"))
        self.names = _means(saved.get("names"))
        self.ratios = _means(saved.get("ratios"))     # absent before format 3

    def estimate(self, kind: str, name: str | None = None, params: Mapping[str, Any] | None = None) -> float:
        """The job's own mean if it ran here before; else, for a kind that tells its jobs apart by params
        (`typical_for`: a lap with a tolerance search is a dozen laps), what it says of these params,
        scaled by how its guesses compared with what its jobs took here; else the kind's mean here, else
        what the kind says its jobs typically take, else the median kind's (a kind never run here is not
        charged the mean of a few slow ones, a training's)."""
        if name is not None and name in self.names:
            return self.names[name][0]
        found = KINDS.get(kind) if kind in KINDS else None
        typical = _typical(found, params) if found is not None else None
        if typical and found.typical_for is not None:
            return typical * self.ratios.get(kind, [1.0])[0]
        if kind in self.means:
            return self.means[kind][0]
        if typical:
            return typical
        known = sorted(mean for mean, _ in self.means.values())
        return known[len(known) // 2] if known else DEFAULT_ESTIMATE_S

    def measured(self, kind: str) -> bool:
        """Whether the kind's estimates rest on what its jobs took on this store."""
        return kind in (self.ratios if _guessing_by_params(kind) is not None else self.means)

    def add(self, kind: str, seconds: float, name: str | None = None,
            params: Mapping[str, Any] | None = None) -> None:
        """Count a finished job; with its `params`, also how its kind's guess compared."""
        _add_to(self.means, kind, seconds)
        found = _guessing_by_params(kind)
        if params is not None and found is not None and (typical := _typical(found, params)) and seconds > 0:
            _add_to(self.ratios, kind, seconds / typical)
        if name is not None:
            self.names.pop(name, None)                # re-inserted last: the oldest names go first
            _add_to(self.names, name, seconds)
            for old in list(self.names)[:max(0, len(self.names) - MAX_NAMES)]:
                del self.names[old]

    def save(self) -> None:
        try:
            write_json_atomic(self.path, {"format": STATS_FORMAT, "kinds": self.means, "names": self.names,
                                          "ratios": self.ratios})
        except OSError:
            pass  # estimates are a nicety; a read-only store still runs


def _guessing_by_params(kind: str) -> JobKind | None:
    """The registered kind, where it guesses its jobs' times by their params (`typical_for`)."""
    found = KINDS.get(kind) if kind in KINDS else None
    return found if found is not None and found.typical_for is not None else None


def _typical(kind: JobKind, params: Mapping[str, Any] | None) -> float | None:
    """What the kind says a job with `params` typically takes; None when it does not say (or its guess
    fails or is not a positive number: a guess never stops a run)."""
    try:
        seconds = kind.typical(params or {})
    except Exception:   # a domain's guess that trips on odd params: no guess
        return None
    return seconds if seconds is not None and 0 < seconds < math.inf else None


def _means(saved: object) -> dict[str, list[float]]:
    """The {slot: [mean, count]} entries of a saved mapping that are that (a damaged file loses those only)."""
    if not isinstance(saved, dict):
        return {}
    return {slot: [float(value[0]), int(value[1])] for slot, value in saved.items()
            if isinstance(value, list) and len(value) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)}


def _add_to(means: dict[str, list[float]], slot: str, seconds: float) -> None:
    mean, count = means.get(slot, [0.0, 0])
    count = min(count + 1, 20)  # a moving mean: recent runs matter more
    means[slot] = [mean + (seconds - mean) / count, count]
