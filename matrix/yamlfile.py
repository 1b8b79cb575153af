"""Safe YAML loading that remembers the line of every key, so errors can say file:line.

Duplicate keys are errors (PyYAML silently keeps the last one, which hides typos).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from matrix.errors import RecipeError

Lines = dict[tuple, int]


def load_yaml(text: str, file: str = "<recipe>") -> tuple[Any, Lines]:
    """(data, lines) where lines maps a key path such as ("models", "pilotnet", "lr") to its line."""
    loader = None
    try:
        loader = yaml.SafeLoader(text)  # the reader already rejects unprintable characters
        node = loader.get_single_node()
        lines: Lines = {}
        data = _build(loader, node, (), lines, file) if node is not None else None
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark else None
        raise RecipeError(f"not valid YAML: {error.problem or error}", file=file, line=line) from None
    except yaml.YAMLError as error:
        raise RecipeError(f"not valid YAML: {error}", file=file) from None
    except RecursionError:
        raise RecipeError("not valid YAML here: an alias refers to itself", file=file) from None
    finally:
        if loader is not None:
            loader.dispose()
    return data, lines


def read_yaml(path: Path) -> tuple[Any, Lines, str]:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise RecipeError(f"cannot read the recipe: {error}", file=str(path)) from None
    data, lines = load_yaml(text, str(path))
    return data, lines, text


def _build(loader: yaml.SafeLoader, node: yaml.Node, path: tuple, lines: Lines, file: str) -> Any:
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        return _build_mapping(loader, node, path, lines, file)
    if isinstance(node, yaml.SequenceNode):
        return [_build(loader, item, path + (i,), lines, file) for i, item in enumerate(node.value)]
    return loader.construct_object(node)


def _build_mapping(loader, node, path, lines, file) -> dict:
    loader.flatten_mapping(node)  # resolves `<<: *anchor` merge keys
    result: dict = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node)
        if not isinstance(key, (str, int, float, bool)) and key is not None:
            raise RecipeError("mapping keys must be plain scalars", file=file,
                              line=key_node.start_mark.line + 1, path=path)
        if key in result:
            raise RecipeError(f"duplicate key {key!r}", file=file, line=key_node.start_mark.line + 1,
                              path=path)
        lines[path + (key,)] = key_node.start_mark.line + 1
        result[key] = _build(loader, value_node, path + (key,), lines, file)
    return result
