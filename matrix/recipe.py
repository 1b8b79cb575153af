"""Recipes: one YAML file -> a validated, typed object and the grid of combinations.

The engine validates the generic part (`name`, `description`, `matrix`); the domain contributes the
schema of its own sections (pydantic types) and the axes a combination may carry. Every error names
the file, the line and the key path, says what was expected and suggests the closest known name.
"""
from __future__ import annotations

import re
import typing
from collections.abc import Callable, Collection, Hashable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pydantic

from matrix.errors import RecipeError, did_you_mean, shown
from matrix.grid import RESERVED, Grid, expand_classes
from matrix.yamlfile import Lines, read_yaml

AxisValues = Callable[["Recipe"], Collection[Any] | None]   # a recipe (its config, its file) -> its values
SameValue = Callable[[Any, str, Any], Hashable | None]   # (config, axis, value) -> matrix.grid.Same


@dataclass(frozen=True)
class Domain:
    """What a domain plugs into the engine."""
    name: str
    sections: Mapping[str, tuple[Any, Any]]   # recipe key -> (pydantic type, default; ... = required)
    axes: Mapping[str, AxisValues]             # known combination keys -> valid values (None: any)
    plan: Callable[[Recipe], list]             # validated recipe -> jobs (matrix.jobs.Job)
    kind_modules: tuple[str, ...] = ()         # imported (in workers too) to register job kinds
    store_env: str = "MATRIX_STORE"
    default_store: str = ".matrix"
    after_run: Callable[..., None] | None = None   # (recipe, plan, summary, store) after `run`
    # Values of an axis that plan the same jobs (two names of one definition): planned once (matrix.grid);
    # it is asked about every value written on an axis, known or not (None: unlike any other)
    same: SameValue | None = None
    # gc: why a stored job no recipe reaches here is kept all the same (a spec -> a reason, or None): a job
    # planned on another machine that shares the store (its timings), which this machine's plan cannot reach
    kept_elsewhere: Callable[[dict], str | None] | None = None


@dataclass(frozen=True)
class Recipe:
    name: str
    description: str
    file: str
    text: str
    config: Any                          # the validated pydantic model (domain sections as attributes)
    combinations: list[dict[str, Any]]   # what the domain plans: one per class of alike cells (matrix.grid)
    lines: Lines = field(repr=False, default_factory=dict)
    grid: Grid | None = field(repr=False, default=None)   # every cell, by way of its combination

    def error(self, message: str, path: Sequence[Any]) -> RecipeError:
        """A RecipeError pointing at `path` in this recipe (for the domain's own checks)."""
        return RecipeError(message, file=self.file, line=line_of(self.lines, tuple(path)), path=path)


def load_recipe(path: Path | str, domain: Domain) -> Recipe:
    data, lines, text = read_yaml(Path(path))
    file = str(path)
    if not isinstance(data, dict):
        raise RecipeError("a recipe is a mapping with at least `name` and `matrix`", file=file, line=1)
    config = _validate(data, lines, file, domain)
    same = (lambda axis, value: domain.same(config, axis, value)) if domain.same else None
    try:
        grid = expand_classes(config.matrix, same)
    except RecipeError as error:
        raise RecipeError(error.message, file=file,
                          line=line_of(lines, error.path), path=error.path) from None
    if not grid.combinations:
        why = ("has no combinations left after `exclude`" if grid.axes else
               "names no axis: give each axis a list of values (`model: [a, b]`), or entries in `include`")
        raise RecipeError(f"the matrix {why}", file=file, line=line_of(lines, ("matrix",)), path=["matrix"])
    recipe = Recipe(config.name, config.description, file, text, config, grid.combinations, lines, grid)
    _check_combinations(recipe, domain)
    return recipe


NAME_LENGTH = 120   # the name names files and folders (a report's, a run's record): most systems allow 255 bytes


def recipe_model(domain: Domain) -> type[pydantic.BaseModel]:
    fields = {key: (annotation, default) for key, (annotation, default) in domain.sections.items()}
    return pydantic.create_model(
        "Recipe", __config__=pydantic.ConfigDict(extra="forbid", frozen=True),
        name=(pydantic.constr(min_length=1, max_length=NAME_LENGTH), ...), description=(str, ""),
        matrix=(dict[str, Any], ...), **fields)


def line_of(lines: Lines, path: tuple) -> int | None:
    """The line of `path`, or of its closest ancestor that has one."""
    for end in range(len(path), -1, -1):
        if path[:end] in lines:
            return lines[path[:end]]
    return None


def _validate(data: dict, lines: Lines, file: str, domain: Domain) -> Any:
    model = recipe_model(domain)
    try:
        return model.model_validate(data)
    except pydantic.ValidationError as error:
        raise _recipe_error(error, data, lines, file, model) from None


def _recipe_error(error: pydantic.ValidationError, data: Any, lines: Lines, file: str,
                  model: type) -> RecipeError:
    # A typo'd key also makes the key it meant "missing": report the typo, it is the cause.
    errors = error.errors(include_url=False)
    first = min(errors, key=lambda e: e["type"] != "extra_forbidden")
    path = _data_path(data, first["loc"], first["type"] == "missing")
    # a union's arms each give an error at the same place: one message says what each would take
    arms = [e for e in errors if e["type"] not in ("extra_forbidden", "missing")
            and _data_path(data, e["loc"], False) == path] if first["type"] != "extra_forbidden" else []
    message = _union_message(arms, data, path) if len(arms) > 1 else _message(first, path, model)
    others = [e for e in errors if e is not first and e not in arms]
    if others:
        message += f" (and {len(others)} more problem{'s' if len(others) > 1 else ''}: {_others(others, data, model)})"
    return RecipeError(message, file=file, line=line_of(lines, tuple(path)), path=path)


def _others(errors: list[dict], data: Any, model: type, shown_at_most: int = 3) -> str:
    """Where the other problems are, each in a few words (the first is the message)."""
    said = []
    for err in errors[:shown_at_most]:
        path = _data_path(data, err["loc"], err["type"] == "missing")
        text = _message(err, path, model)
        said.append(f"{'.'.join(map(str, path)) or 'the recipe'}: {text if len(text) <= 80 else text[:79] + '…'}")
    return "; ".join(said) + ("; …" if len(errors) > shown_at_most else "")


def _message(err: dict, path: list, model: type) -> str:
    kind = err["type"]
    if kind == "extra_forbidden":
        known = _fields_at(model, path[:-1])
        return (f"unknown key {path[-1]!r}{did_you_mean(path[-1], known)}; "
                f"expected one of: {', '.join(sorted(known)) or '(none)'}")
    if kind == "missing":
        return f"missing required key {path[-1]!r}"
    if kind == "value_error":  # a domain validator's own sentence
        return err["msg"].removeprefix("Value error, ")
    if kind == "model_type":   # "...or instance of ModelSpec": a class name the recipe never shows
        return f"{_key_of(path)}should be a mapping of keys to values ({{key: value, ...}}) (got {_given(err.get('input'))})"
    given = err.get("input")
    return f"{err['msg']} (got {_given(given)}){_literal_guess([err], given)}"


def _union_message(arms: list[dict], data: Any, path: list) -> str:
    """`arms`: the errors of a value that fits no arm of a union, e.g. 'explicit' or 'expert', or a mapping."""
    given = arms[0].get("input")
    wanted = " or ".join(dict.fromkeys(e["msg"].removeprefix("Input should be ") for e in arms))
    return f"{_key_of(path)}should be {wanted} (got {_given(given)}){_literal_guess(arms, given)}"


def _key_of(path: list) -> str:
    return f"{path[-1]!r} " if path and isinstance(path[-1], str) else ""


def _literal_guess(errors: list[dict], given: Any) -> str:
    """'did you mean' among the literal values the errors name, for a string given."""
    if not isinstance(given, str):
        return ""
    options = [v for e in errors if e["type"] == "literal_error"
               for v in re.findall(r"'([^']*)'", str((e.get("ctx") or {}).get("expected", "")))]
    return did_you_mean(given, options) if options else ""


def _given(given: Any) -> str:
    return shown(given) if not isinstance(given, (dict, list)) else type(given).__name__


def _data_path(data: Any, loc: tuple, missing: bool = False) -> list:
    """The part of a pydantic error location that indexes into the data (drops union tags such as
    "literal['a','b']"); `missing`: the last part is a key the data lacks (a missing key's name)."""
    path, current = [], data
    for i, part in enumerate(loc):
        if isinstance(current, dict) and part in current:
            path.append(part)
            current = current[part]
        elif isinstance(current, list) and isinstance(part, int) and part < len(current):
            path.append(part)
            current = current[part]
        elif i == len(loc) - 1 and missing:
            path.append(part)
    return path


def _fields_at(model: Any, path: Sequence[Any]) -> list[str]:
    """Field names of the pydantic model found at `path` below `model` ([] when unknown)."""
    candidates = [model]
    for part in path:
        candidates = [child for c in candidates for child in _children(c, part)]
    return sorted({name for c in candidates if _is_model(c) for name in c.model_fields})


def _children(annotation: Any, part: Any) -> list[Any]:
    if _is_model(annotation):
        info = annotation.model_fields.get(part)
        return _unwrap(info.annotation) if info else []
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (dict, Mapping) and len(args) == 2:
        return _unwrap(args[1])
    if origin in (list, tuple, Sequence) and args:
        return _unwrap(args[0])
    return []


def _unwrap(annotation: Any) -> list[Any]:
    """Union / Optional / Annotated arms, flattened."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        return [arm for arg in typing.get_args(annotation) for arm in _unwrap(arg)]
    return [annotation]


def _is_model(annotation: Any) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, pydantic.BaseModel)


def _check_combinations(recipe: Recipe, domain: Domain) -> None:
    """Every key of every combination is an axis the domain knows, with a value it accepts."""
    matrix = recipe.config.matrix
    valid = {axis: values(recipe) for axis, values in domain.axes.items()}
    for path, key, value in declared_values(matrix):
        if key not in domain.axes:
            key_path = path if path[1] in RESERVED else path[:2]
            raise recipe.error(f"unknown axis {key!r}{did_you_mean(key, domain.axes)}; "
                               f"known axes: {', '.join(domain.axes)}", key_path)
        if not isinstance(value, (str, int, float, bool)):
            raise recipe.error(f"axis values are plain names or numbers, got {shown(value)}", path)
        known = valid[key]
        if known is not None and value not in known:
            raise recipe.error(f"unknown {key} {shown(value)}{did_you_mean(str(value), map(str, known))}; "
                               f"known: {', '.join(map(str, known)) or '(none)'}", path)


def declared_values(matrix: Mapping[str, Any]):
    """(key path, axis, value) for every value written in the matrix section (axes, include, exclude)."""
    for key, values in matrix.items():
        if key in RESERVED:
            for i, entry in enumerate(matrix[key] or []):
                for axis, value in entry.items():
                    yield ["matrix", key, i, axis], axis, value
        else:
            for i, value in enumerate(values):
                yield ["matrix", key, i], key, value
