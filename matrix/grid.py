"""Grid expansion with GitHub Actions `strategy.matrix` semantics.

1. The product of the axes, in declared order (the last axis varies fastest).
2. `exclude`: every combination that an entry partially matches is removed.
3. `include`, entry by entry: the entry's keys are added to every original combination where none
   of them would overwrite an original (axis) value; values added by an earlier include may be
   overwritten. An entry that fits no original combination becomes a new combination. Combinations
   created by include are never extended.

Planning cost follows distinct combinations, not cells (`expand_classes`): values of one axis that the
domain calls the same (`same(axis, value)`: two model names with equal definitions) and that every
exclude and include entry treats alike form a class; the grid is expanded over each class's first value
and a combination stands for every cell its classes multiply out to (`Grid.cells` names them all).
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Hashable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from matrix.errors import RecipeError, did_you_mean

RESERVED = ("include", "exclude")
MAX_COMBINATIONS = 1_000_000   # distinct combinations planned; cells that are the same cost nothing
Same = Callable[[str, Any], Hashable | None]   # (axis, value) -> what makes it the same as another; None: itself


@dataclass(frozen=True)
class Grid:
    """The combinations a `matrix:` mapping describes, one per class of cells that plan alike.

    `combinations[i]` holds the first value of each of its classes; for a combination of the axes'
    product (not one an include created) `classes[i]` is the index of its class on each axis."""
    axes: tuple[str, ...]
    members: Mapping[str, list[list[Any]]]     # axis -> its classes, each a list of values (first = shown)
    combinations: list[dict[str, Any]]
    classes: list[tuple[int, ...] | None]

    def stands_for(self, index: int) -> int:
        """How many cells combination `index` stands for."""
        picked = self.classes[index]
        if picked is None:
            return 1
        return math.prod(len(self.members[axis][c]) for axis, c in zip(self.axes, picked))

    def count(self) -> int:
        """Cells in all: as many as GitHub Actions would run."""
        return sum(self.stands_for(i) for i in range(len(self.combinations)))

    def same_as(self, axis: str, value: Any) -> list[Any]:
        """Every value of `axis` in the class whose first value is `value` (just [value] if none)."""
        for values in self.members.get(axis, ()):
            if values[0] == value:
                return list(values)
        return [value]

    def alike(self) -> dict[str, list[tuple[Any, list[Any]]]]:
        """axis -> [(the value a class is planned and shown as, the other values it stands for)], for
        the classes of more than one value."""
        found = {axis: [(values[0], values[1:]) for values in classes if len(values) > 1]
                 for axis, classes in self.members.items()}
        return {axis: pairs for axis, pairs in found.items() if pairs}

    def cells(self) -> Iterator[dict[str, Any]]:
        """Every cell, lazily: each combination multiplied out over its classes' values."""
        for combination, picked in zip(self.combinations, self.classes):
            if picked is None:
                yield dict(combination)
                continue
            choices = [self.members[axis][c] for axis, c in zip(self.axes, picked)]
            for values in itertools.product(*choices):
                yield {**combination, **dict(zip(self.axes, values))}


def describe_alike(grid: Grid, shown: int = 3) -> str | None:
    """One line saying which cells are planned as one ("1,000,000 cells plan as 4 combinations: model
    m1, m2, m3 and 996 more as m0"), or None when every cell is its own combination."""
    alike = grid.alike()
    if not alike:
        return None
    parts = []
    for axis, pairs in alike.items():
        said = [_said(first, others, shown) for first, others in pairs[:shown]]
        more = f" (and {len(pairs) - shown} more groups)" if len(pairs) > shown else ""
        parts.append(f"{axis} " + "; ".join(said) + more)
    count = len(grid.combinations)
    return f"{grid.count():,} cells plan as {count:,} combination{'s' * (count != 1)}: " + "; ".join(parts)


def _said(first: Any, others: list, shown: int) -> str:
    """"m1, m2 as m0", or for a value listed again "baseline listed 2 times" (not "baseline as baseline")."""
    distinct, repeats = [o for o in others if o != first], sum(1 for o in others if o == first)
    said = [f"{_names(distinct, shown)} as {first}"] if distinct else []
    return ", ".join(said + ([f"{first} listed {repeats + 1} times"] if repeats else []))


def _names(values: list, shown: int) -> str:
    listed = ", ".join(map(str, values[:shown]))
    return listed + (f" and {len(values) - shown:,} more" if len(values) > shown else "")


def expand_grid(mapping: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The list of combinations described by a `matrix:` mapping as parsed from YAML."""
    return expand_classes(mapping).combinations


def expand_classes(mapping: Mapping[str, Any], same: Same | None = None) -> Grid:
    """The grid of `mapping`, expanded over classes of values that plan alike (see the module)."""
    if not isinstance(mapping, Mapping):
        raise RecipeError(f"expected a mapping of axes, got {type(mapping).__name__}", path=["matrix"])
    axes = {key: values for key, values in mapping.items() if key not in RESERVED}
    _check_axes(axes)
    excludes = _entries(mapping, "exclude")
    includes = _entries(mapping, "include")
    _check_exclude_keys(excludes, axes)
    members = {axis: _classes(axis, values, same, excludes, includes) for axis, values in axes.items()}
    _check_size(members)
    picks = list(itertools.product(*(range(len(classes)) for classes in members.values()))) if axes else []
    base = [{axis: members[axis][c][0] for axis, c in zip(axes, pick)} for pick in picks]
    kept = [i for i, combo in enumerate(base) if not any(_matches(combo, entry) for entry in excludes)]
    combinations = _apply_includes([base[i] for i in kept], includes)
    classes = [picks[i] for i in kept] + [None] * (len(combinations) - len(kept))
    return Grid(tuple(axes), members, combinations, classes)


def _classes(axis: str, values: list, same: Same | None, excludes: list[dict], includes: list[dict]) -> list[list]:
    """The values of `axis` grouped: same for the domain, and matched alike by every entry."""
    groups: dict[Hashable, list] = {}
    for index, value in enumerate(values):
        identity = same(axis, value) if same is not None else None
        signature = (("value", index) if identity is None else ("same", identity),
                     tuple(_value_matches(value, e[axis]) for e in excludes if axis in e),
                     tuple(value == e[axis] for e in includes if axis in e))
        groups.setdefault(signature, []).append(value)
    return list(groups.values())


def _check_size(members: Mapping[str, list[list]]) -> None:
    """Planning is bounded by distinct combinations (cells that are the same are free)."""
    distinct = math.prod(len(classes) for classes in members.values())
    if distinct > MAX_COMBINATIONS:
        sizes = " × ".join(f"{len(classes)} {axis}" for axis, classes in members.items())
        raise RecipeError(f"the matrix makes {distinct:,} distinct combinations ({sizes}), more than "
                          f"{MAX_COMBINATIONS:,} can be planned; split the recipe or use fewer values", path=["matrix"])


def _apply_includes(originals: list[dict], includes: list[dict]) -> list[dict]:
    extended = [dict(combo) for combo in originals]
    created: list[dict] = []
    for entry in includes:
        fits = [i for i, combo in enumerate(originals) if _fits(combo, entry)]
        for i in fits:
            extended[i].update(entry)
        if not fits:
            created.append(dict(entry))
    return extended + created


def _fits(original: Mapping, entry: Mapping) -> bool:
    """True when no key of `entry` would overwrite a value of the original combination."""
    return all(key not in original or original[key] == value for key, value in entry.items())


def _matches(combo: Mapping, entry: Mapping) -> bool:
    """Partial match: every key of `entry` is in `combo` with an equal (or partially equal) value."""
    return all(key in combo and _value_matches(combo[key], value) for key, value in entry.items())


def _value_matches(actual: Any, wanted: Any) -> bool:
    if isinstance(actual, Mapping) and isinstance(wanted, Mapping):
        return _matches(actual, wanted)
    return actual == wanted


def _check_axes(axes: Mapping[str, Any]) -> None:
    for key, values in axes.items():
        if not isinstance(key, str):
            raise RecipeError(f"axis names must be strings, got {key!r}", path=["matrix"])
        if not isinstance(values, list):
            raise RecipeError(f"an axis is a list of values, got {type(values).__name__}; "
                              f"write `{key}: [{values!r}]`", path=["matrix", key])
        if not values:
            raise RecipeError("an axis needs at least one value (or remove the axis)",
                              path=["matrix", key])


def _entries(mapping: Mapping[str, Any], section: str) -> list[dict]:
    entries = mapping.get(section, [])
    if entries is None:
        return []
    if not isinstance(entries, list):
        raise RecipeError(f"`{section}` is a list of mappings, got {type(entries).__name__}",
                          path=["matrix", section])
    for i, entry in enumerate(entries):
        if not isinstance(entry, Mapping) or not entry:
            raise RecipeError(f"each `{section}` entry is a non-empty mapping of axis: value, got {entry!r}",
                              path=["matrix", section, i])
    return [dict(entry) for entry in entries]


def _check_exclude_keys(excludes: list[dict], axes: Mapping[str, Any]) -> None:
    for i, entry in enumerate(excludes):
        for key in entry:
            if key not in axes:
                raise RecipeError(f"exclude names {key!r}, which is not an axis{did_you_mean(key, axes)}; "
                                  f"axes: {', '.join(axes) or '(none)'}", path=["matrix", "exclude", i, key])
