"""Safe YAML loading that remembers the line of every key, so errors can say file:line.

Duplicate keys are errors (PyYAML silently keeps the last one, which hides typos). A document is
bounded: its text to MAX_TEXT_BYTES, and what it expands to (each alias counted as a copy of what it
names) to MAX_VALUES, so a few nested aliases ("billion laughs") are an error, not hours of work.
"""
from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import yaml

from matrix.errors import RecipeError

Lines = dict[tuple, int]
MAX_TEXT_BYTES = 4 * 2**20
MAX_VALUES = 100_000
# A recipe nests a handful of levels. The bound is ours, not the interpreter's recursion limit (which
# whatever else the process imported may have raised), so a deep document gets the same answer anywhere.
MAX_NESTING = 100
TOO_DEEP = f"not valid YAML here: nested deeper than {MAX_NESTING} levels; a recipe nests a few"
# libyaml's loader (PyYAML's C extension), where PyYAML has it and libyaml bounds nesting (0.2.6 and later:
# 1000 levels; PyYAML's C composer recurses once a level, with no bound of its own); else PyYAML's own.
FAST_LOADER = yaml.CSafeLoader if yaml.__with_libyaml__ and yaml._yaml.get_version() >= (0, 2, 6) else None


def load_yaml(text: str, file: str = "<recipe>") -> tuple[Any, Lines]:
    """(data, lines) where lines maps a key path such as ("models", "pilotnet", "lr") to its line."""
    if len(text) > MAX_TEXT_BYTES:
        raise RecipeError(f"{len(text) / 2**20:.1f} MB is too large for a recipe (at most "
                          f"{MAX_TEXT_BYTES // 2**20} MB); list big data in files the recipe names", file=file)
    loader = None
    try:
        loader, node = _compose(text)
        _check_expansion(node, file)
        lines: Lines = {}
        data = _build(loader, node, (), lines, file) if node is not None else None
    except yaml.MarkedYAMLError as error:
        raise _syntax_error(error, file) from None
    except yaml.reader.ReaderError as error:
        raise _character_error(error, text, file) from None
    except yaml.YAMLError as error:
        raise RecipeError(f"not valid YAML: {' '.join(str(error).split())}", file=file) from None
    except RecursionError:             # the parser's own recursion, on a document nested too deeply
        raise RecipeError(TOO_DEEP, file=file) from None
    finally:
        if loader is not None:
            loader.dispose()
    return data, lines


def _compose(text: str) -> tuple[yaml.SafeLoader, yaml.Node | None]:
    """The document's node tree, and the loader that builds values from it. libyaml's parser reads a
    recipe about five times faster than PyYAML's own; a document it rejects is read again by PyYAML's,
    whose errors (and where they point) the messages here are written for. Both reject unprintable
    characters; libyaml also takes a tab inside a plain scalar, as YAML allows (PyYAML refuses it)."""
    if FAST_LOADER is not None:
        try:
            loader = FAST_LOADER(text)      # UnicodeError: a lone surrogate, which libyaml cannot take
            return loader, loader.get_single_node()
        except (yaml.YAMLError, UnicodeError):
            pass
    loader = yaml.SafeLoader(text)
    return loader, loader.get_single_node()


def read_yaml(path: Path) -> tuple[Any, Lines, str]:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RecipeError(f"no such file{_nearby(Path(path))}", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as error:
        raise RecipeError(f"cannot read the recipe: {str(error)[:300]}", file=str(path)[:300]) from None
    data, lines = load_yaml(text, str(path))
    return data, lines, text


def _nearby(path: Path) -> str:
    """'; did you mean recipes/x.yaml?' for YAML files near `path` with a close name (or a list)."""
    folders = dict.fromkeys(f for f in (path.parent, path.parent / "recipes", Path("recipes")) if f.is_dir())
    try:
        found = [p for folder in folders for p in sorted(folder.iterdir()) if p.suffix in (".yaml", ".yml")]
    except OSError:
        return ""
    by_name = {}
    for candidate in found:
        by_name.setdefault(candidate.name, candidate)
    close = difflib.get_close_matches(path.name, list(by_name), n=3, cutoff=0.6)
    if close:
        return "; did you mean " + " or ".join(str(by_name[name]) for name in close) + "?"
    if by_name:
        return "; recipes nearby: " + ", ".join(str(p) for p in list(by_name.values())[:5])
    return ""


def _check_expansion(root: yaml.Node | None, file: str) -> None:
    """Count the values the document expands to (linear time: each node's count is remembered), and
    bound its nesting."""
    counts: dict[int, int] = {}

    def count(node: yaml.Node, depth: int) -> int:
        if depth > MAX_NESTING:
            raise RecipeError(TOO_DEEP, file=file)
        if id(node) not in counts:
            counts[id(node)] = -1            # in progress: meeting it again means an alias cycle
            if isinstance(node, yaml.MappingNode):
                children = [n for pair in node.value for n in pair]
            else:
                children = node.value if isinstance(node, yaml.SequenceNode) else []
            counts[id(node)] = 1 + sum(count(child, depth + 1) for child in children)
        if counts[id(node)] < 0:
            raise RecipeError("not valid YAML here: an alias refers to itself", file=file)
        return counts[id(node)]

    total = count(root, 0) if root is not None else 0
    if total > MAX_VALUES:
        raise RecipeError(f"the document expands to {total:.3g} values through its aliases (at most "
                          f"{MAX_VALUES:,}); write the values out or use fewer nested aliases (*name)", file=file)


def _build(loader: yaml.SafeLoader, node: yaml.Node, path: tuple, lines: Lines, file: str) -> Any:
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        return _build_mapping(loader, node, path, lines, file)
    if isinstance(node, yaml.SequenceNode):
        return [_build(loader, item, path + (i,), lines, file) for i, item in enumerate(node.value)]
    return loader.construct_object(node)


def _build_mapping(loader, node, path, lines, file) -> dict:
    own = {id(key_node) for key_node, _ in node.value}   # the keys written here, not merged in
    loader.flatten_mapping(node)  # resolves `<<: *anchor` merge keys: the merged pairs come first
    result: dict = {}
    written: set = set()
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node)
        if not isinstance(key, (str, int, float, bool)) and key is not None:
            raise RecipeError("mapping keys must be plain scalars", file=file,
                              line=key_node.start_mark.line + 1, path=path)
        if id(key_node) in own:       # a key written here overrides a merged one, as YAML's merge says
            if key in written:
                raise RecipeError(f"duplicate key {key!r}", file=file, line=key_node.start_mark.line + 1,
                                  path=path)
            written.add(key)
        lines[path + (key,)] = key_node.start_mark.line + 1
        result[key] = _build(loader, value_node, path + (key,), lines, file)
    return result


# What an unclosed construct is called, by PyYAML's context: the error points where it was opened
# (PyYAML finds the problem where the next construct starts, often a line later).
_OPENED = {"flow mapping": "this { mapping } is not closed", "flow sequence": "this [ list ] is not closed",
           "quoted scalar": "this quoted string is not closed", "simple key": "this key has no ':' after it"}


def _syntax_error(error: yaml.MarkedYAMLError, file: str) -> RecipeError:
    """One line: file:line:column where the problem is (or where the construct it concerns began)."""
    problem, mark, context = error.problem or str(error), error.problem_mark, error.context or ""
    opened = next((text for key, text in _OPENED.items() if key in context), None)
    if opened and error.context_mark is not None:
        where = error.context_mark
        detail = f"{problem} at line {mark.line + 1}, column {mark.column + 1}" if mark else problem
        return RecipeError(f"not valid YAML: {opened} ({detail})", file=file, line=where.line + 1,
                           column=where.column + 1)
    mark = mark or error.context_mark
    if problem.startswith("expected <block end>"):
        problem = _block_end_problem(problem)
    return RecipeError(f"not valid YAML: {' '.join(problem.split())}", file=file,
                       line=mark.line + 1 if mark else None, column=mark.column + 1 if mark else None)


def _block_end_problem(problem: str) -> str:
    """PyYAML's 'expected <block end>': after a flow collection's bracket ({...}, [...]) found closed, a
    bracket closed one too many or too early; otherwise, an indentation that matches no level."""
    if any(f"found '{token}'" in problem for token in ",]}"):
        return f"a '}}' or ']' before this closes more than was opened, or closes it too early ({problem})"
    return f"this line is indented differently from the lines around it ({problem})"


def _character_error(error: yaml.reader.ReaderError, text: str, file: str) -> RecipeError:
    """A control character (or an unpaired surrogate): where it is, and which one."""
    before = text[:error.position]
    line, column = before.count("\n") + 1, error.position - (before.rfind("\n") + 1) + 1
    code = error.character if isinstance(error.character, int) else ord(str(error.character)[:1] or "\0")
    return RecipeError(f"not valid YAML: character U+{code:04X} (a control character or a lone surrogate) is "
                       "not allowed; remove it (inside double quotes, escapes such as \\t or \\x07 write one)",
                       file=file, line=line, column=column)
