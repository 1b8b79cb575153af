"""Grid expansion with GitHub Actions `strategy.matrix` semantics.

1. The product of the axes, in declared order (the last axis varies fastest).
2. `exclude`: every combination that an entry partially matches is removed.
3. `include`, entry by entry: the entry's keys are added to every original combination where none
   of them would overwrite an original (axis) value; values added by an earlier include may be
   overwritten. An entry that fits no original combination becomes a new combination. Combinations
   created by include are never extended.
"""
from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

from matrix.errors import RecipeError, did_you_mean

RESERVED = ("include", "exclude")


def expand_grid(mapping: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The list of combinations described by a `matrix:` mapping as parsed from YAML."""
    if not isinstance(mapping, Mapping):
        raise RecipeError(f"expected a mapping of axes, got {type(mapping).__name__}", path=["matrix"])
    axes = {key: values for key, values in mapping.items() if key not in RESERVED}
    _check_axes(axes)
    excludes = _entries(mapping, "exclude")
    includes = _entries(mapping, "include")
    _check_exclude_keys(excludes, axes)
    base = _product(axes)
    kept = [combo for combo in base if not any(_matches(combo, entry) for entry in excludes)]
    return _apply_includes(kept, includes)


def _product(axes: Mapping[str, list]) -> list[dict[str, Any]]:
    if not axes:
        return []
    names = list(axes)
    return [dict(zip(names, values)) for values in itertools.product(*axes.values())]


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
