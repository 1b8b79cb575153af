"""Content fingerprints of code: what implements a job kind (input files: matrix.inputhash).

Code is fingerprinted by its source text without comments, docstrings and blank lines
(`code_text`), so editing a strategy's module changes the keys of that strategy's jobs and nothing
else, and rewording a comment or a docstring changes none; which modules a module imports is read
from its source, parsed once per text (the names are remembered across processes by its sha256),
and a whole closure is remembered with the file hashes and folder listings it was read from.
"""
from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import tokenize
from collections.abc import Iterable, Iterator
from io import BytesIO, StringIO
from pathlib import Path
from types import ModuleType
from typing import Any

from matrix.errors import MatrixError
from matrix.hashcache import HASH_CACHE
from matrix.inputhash import forget_file_hashes, hash_path

_SOURCE_HASHES: dict[Any, str] = {}
_ORIGINS: dict[str, Path] = {}
_FOLDERS: dict[str, frozenset[str]] = {}
_GENERATION = [0]   # bumped by clear_caches: whatever was derived from source text is stale


def code_fingerprint(sources: Iterable[Any]) -> str:
    """sha256 over the source text of the modules (or packages) that define `sources`: modules,
    module names, functions or classes."""
    digest = hashlib.sha256()
    for ident, text_hash in sorted(_source_hash(source) for source in sources):
        digest.update(f"{ident}:{text_hash}\n".encode())
    return digest.hexdigest()


def closure_fingerprint(modules: Iterable[str], extra: Iterable[Any] = ()) -> str:
    """sha256 over the modules' own source files (a package counts as its `__init__.py`: what it
    imports is in the closure by name) and over `extra`: code sources as in `code_fingerprint`, or
    paths of files a job reads that no import names (data tables, templates)."""
    digest = hashlib.sha256()
    entries = [_own_source_hash(module) for module in modules] + [_extra_hash(e) for e in extra]
    for ident, text_hash in sorted(set(entries)):
        digest.update(f"{ident}:{text_hash}\n".encode())
    return digest.hexdigest()


def _own_source_hash(module: str) -> tuple[str, str]:
    ident = f"{module}#own"
    if ident not in _SOURCE_HASHES:
        _SOURCE_HASHES[ident] = _code_sha256(_module_origin(module))
    return ident, _SOURCE_HASHES[ident]


def _extra_hash(source: Any) -> tuple[str, str]:
    if isinstance(source, (str, Path)) and ("/" in str(source) or Path(source).is_file()):
        return f"file:{Path(source).name}", hash_path(source)
    return _source_hash(source)


def _ident(source: Any) -> str:
    """The module a source lives in: code is fingerprinted a whole module at a time (one job kind,
    one strategy, one model per module keeps that precise)."""
    if isinstance(source, str):
        return source
    if isinstance(source, ModuleType):
        return source.__name__
    return source.__module__


def _source_hash(source: Any) -> tuple[str, str]:
    ident = _ident(source)
    if ident not in _SOURCE_HASHES:
        origin = _module_origin(ident)
        _SOURCE_HASHES[ident] = hashlib.sha256(_package_text(origin).encode()).hexdigest() \
            if origin.name == "__init__.py" else _code_sha256(origin)   # a module's: read once for both uses
    return ident, _SOURCE_HASHES[ident]


def _module_origin(name: str) -> Path:
    """The module's file, remembered in the process (until `clear_caches`): a closure asks for the
    same few hundred modules thousands of times."""
    if name not in _ORIGINS:
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None:
            raise MatrixError(f"cannot find module {name!r} to fingerprint its code")
        _ORIGINS[name] = Path(spec.origin)
    return _ORIGINS[name]


def _package_text(origin: Path) -> str:
    """A package's code (`origin`: its `__init__.py`): every .py file below it, in a fixed order."""
    files = sorted(origin.parent.rglob("*.py"))
    return "".join(f"# {f.relative_to(origin.parent)}\n{source_code_text(f.read_bytes())}\n" for f in files)


CODE_TEXT_VERSION = 3   # in the remembered closures' key: a change of code_text re-reads them
CLOSURE_VERSION = 2     # the same for what a closure holds (2: the packages above each module)


def python_source(data: bytes) -> str | None:
    """A source file's text as Python reads it: by its BOM or its coding line (PEP 263), else UTF-8;
    None where it does not decode (Python would refuse to import it)."""
    try:
        encoding, _ = tokenize.detect_encoding(BytesIO(data).readline)
        return data.decode(encoding)
    except (SyntaxError, LookupError, UnicodeDecodeError):
        return None


def source_code_text(data: bytes) -> str:
    """`code_text` of a source file's bytes; a file that does not decode is kept whole (escaped)."""
    text = python_source(data)
    return code_text(text) if text is not None else data.decode("utf-8", errors="backslashreplace")


def code_text(source: str) -> str:
    """`source` without its comments, docstrings, trailing spaces and blank lines: what a code
    fingerprint hashes, so that rewording a comment or a docstring reruns nothing. The rest is kept
    as written (what is left of a line keeps its place, and the lines of a multi-line string keep
    their spaces and blank lines), so the text is the same under every Python that parses it; a
    source that does not parse is kept whole."""
    source = source.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n")
    try:
        tree = ast.parse(source)
        comments = _comment_spans(source)
    except (SyntaxError, tokenize.TokenError, ValueError):
        return source
    lines = source.split("\n")   # rows as tokenize and ast count them (not str.splitlines: \x0c, \u2028...)
    docstrings = _docstring_spans(tree, lines)
    as_written = _string_rows(tree, {start for start, _ in docstrings})
    for (first_row, first_col), (last_row, last_col) in sorted(comments + docstrings, reverse=True):
        head, tail = lines[first_row - 1][:first_col], lines[last_row - 1][last_col:]
        lines[first_row - 1:last_row] = [head + tail] + [""] * (last_row - first_row)
    kept = (line if row in as_written else line.rstrip() for row, line in enumerate(lines, 1))
    return "\n".join(line for row, line in enumerate(kept, 1) if line or row in as_written)


def _comment_spans(source: str) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    tokens = tokenize.generate_tokens(StringIO(source).readline)
    return [(token.start, token.end) for token in tokens if token.type == tokenize.COMMENT]


def _docstring_spans(tree: ast.Module, lines: list[str]) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """The (row, column) spans of the docstrings of the module, its classes and functions (ast's
    columns count UTF-8 bytes; these count characters, as tokenize's do)."""
    spans = []
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body and \
                isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) and \
                isinstance(body[0].value.value, str):
            doc = body[0]
            spans.append(((doc.lineno, _chars(lines[doc.lineno - 1], doc.col_offset)),
                          (doc.end_lineno, _chars(lines[doc.end_lineno - 1], doc.end_col_offset))))
    return spans


def _string_rows(tree: ast.Module, docstring_starts: set[tuple[int, int]]) -> set[int]:
    """Rows that end inside a multi-line string (not a docstring) or begin inside one: their spaces and
    blank lines are the string's, kept as written."""
    rows = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Constant, ast.JoinedStr)) and node.end_lineno > node.lineno and \
                (isinstance(node, ast.JoinedStr) or isinstance(node.value, (str, bytes))) and \
                node.lineno not in {row for row, _ in docstring_starts}:
            rows.update(range(node.lineno, node.end_lineno))
    return rows


def _chars(line: str, utf8_offset: int) -> int:
    return len(line.encode("utf-8")[:utf8_offset].decode("utf-8", errors="ignore"))


def module_closure(name: str, within: str, exclude: Iterable[str] = ()) -> list[str]:
    """`name` and the modules below package `within` that it imports, transitively (imports inside
    functions included), and the packages above each (their `__init__.py` runs first: see
    `_packages_above`), found by reading the source: nothing is imported, so a domain can name the
    code behind a job without loading the heavy libraries that code uses. Modules in `exclude` (and
    what only they import) are left out: shared code a kind fingerprints anyway. A closure is
    remembered in the process (until `clear_caches`) and across processes with what it was read from
    (each file's sha256, each package folder's modules), believed only while all of that still holds."""
    skip = tuple(sorted(set(exclude)))
    memo = (_GENERATION[0], name, within, skip)
    if memo not in _CLOSURES:
        _CLOSURES[memo] = _remembered_closure(name, within, skip)
    return list(_CLOSURES[memo])


_CLOSURES: dict[tuple, tuple[str, ...]] = {}


def _remembered_closure(name: str, within: str, skip: tuple[str, ...]) -> tuple[str, ...]:
    where = [name, within, list(skip), str(_module_origin(within)),   # another checkout: another closure
             CODE_TEXT_VERSION, CLOSURE_VERSION]
    key = hashlib.sha256(json.dumps(where).encode()).hexdigest()
    record = HASH_CACHE.get_closure(key)
    if record is not None and _facts_hold(record.get("facts")):
        return tuple(record["modules"])
    found, facts = _walked_closure(name, within, set(skip))
    if not facts.unknown:
        HASH_CACHE.put_closure(key, {"modules": found, "facts": facts.as_dict()})
    HASH_CACHE.commit()
    return tuple(found)


def _walked_closure(name: str, within: str, skip: set[str]) -> tuple[list[str], _Facts]:
    found: list[str] = []
    walked: set[str] = set()
    facts, pending = _Facts(), [name]
    while pending:
        module = pending.pop()
        if module in walked or module in skip:
            continue
        walked.add(module)
        if module not in found:   # a package may be found first as the one above a module
            found.append(module)
        imported, read_from = _imported_modules(module, within)
        facts.merge(read_from)
        pending += imported
        for package in _packages_above(module, within):
            if package not in found and package not in skip and _has_file(package):   # (not a namespace package)
                found.append(package)
                facts.files[package] = _file_facts(package)
    return found, facts


def _has_file(module: str) -> bool:
    """Whether the module has a file (a namespace package, a folder without `__init__.py`, runs no code)."""
    try:
        _module_origin(module)
    except MatrixError:
        return False
    return True


def _packages_above(module: str, within: str) -> list[str]:
    """The packages whose `__init__.py` runs before `module` can (those below `within`, and `within`):
    'pilotlab.sim.env' -> ['pilotlab', 'pilotlab.sim']. Their own code is in the closure; what they
    import is followed only where a module imports it by name (a package that imports its members to
    register them would otherwise make every member the code of every job)."""
    parts = module.split(".")
    return [".".join(parts[:end]) for end in range(within.count(".") + 1, len(parts))]


class _Facts:
    """What reading a module's imports rests on: the files read (module -> path, sha256), the module
    files that only had to exist (a package's `__init__.py`) and the package folders listed. A closure
    that named a package not found (`unknown`) is not remembered: nothing here would tell it appeared."""

    def __init__(self) -> None:
        self.files: dict[str, list[str]] = {}
        self.exists: set[str] = set()
        self.folders: dict[str, list[str]] = {}
        self.unknown: set[str] = set()

    def merge(self, other: _Facts) -> None:
        self.files |= other.files
        self.exists |= other.exists
        self.folders |= other.folders
        self.unknown |= other.unknown

    def as_dict(self) -> dict:
        return {"files": self.files, "exists": sorted(self.exists), "folders": self.folders}


def _facts_hold(facts: dict | None) -> bool:
    """Whether a remembered closure's facts are still true (each file's raw sha256); the code hashes
    remembered beside them are kept for the code fingerprint (`_own_source_hash`)."""
    try:
        files = facts["files"]
        if any(_file_sha256(path) != sha for path, sha, _ in files.values()) or \
                not all(_is_file(path) for path in facts["exists"]) or \
                any(sorted(_modules_in(folder)) != names for folder, names in facts["folders"].items()):
            return False
    except (OSError, TypeError, KeyError, ValueError, AttributeError):   # gone, or a damaged record: re-read
        return False
    for module, (path, _, code_sha) in files.items():
        if module not in _ORIGINS:
            _ORIGINS[module] = Path(path)
            _SOURCE_HASHES.setdefault(f"{module}#own", code_sha)
    return True


def _file_sha256(path: Path | str) -> str:
    """A source file's sha256, read once per process (until `clear_caches`): closures share most files."""
    path = os.fspath(path)   # (paths as text: a closure's check looks up some thousand of them)
    if path not in _SOURCE_FILES:
        with open(path, "rb") as source:
            _SOURCE_FILES[path] = hashlib.sha256(source.read()).hexdigest()
    return _SOURCE_FILES[path]


_SOURCE_FILES: dict[str, str] = {}


def _code_sha256(path: Path | str) -> str:
    """sha256 of a source file's `code_text`, once per process and text."""
    raw = _file_sha256(path)
    if raw not in _CODE_HASHES:
        with open(path, "rb") as source:
            _CODE_HASHES[raw] = hashlib.sha256(source_code_text(source.read()).encode()).hexdigest()
    return _CODE_HASHES[raw]


_CODE_HASHES: dict[str, str] = {}


def _is_file(path: str) -> bool:
    if path not in _FILES_FOUND:
        _FILES_FOUND[path] = os.path.isfile(path)
    return _FILES_FOUND[path]


_FILES_FOUND: dict[str, bool] = {}


_IMPORTS: dict[tuple, tuple[list[str], _Facts]] = {}


def _imported_modules(name: str, within: str) -> tuple[list[str], _Facts]:
    """The modules below package `within` that `name`'s source imports, and what telling rests on
    (read once per process, until `clear_caches`)."""
    key = (_GENERATION[0], name, within)
    if key not in _IMPORTS:
        _IMPORTS[key] = _read_imports(name, within)
    return _IMPORTS[key]


def _read_imports(name: str, within: str) -> tuple[list[str], _Facts]:
    origin, facts = _module_origin(name), _Facts()
    facts.files[name] = _file_facts(name)
    package = name if origin.name == "__init__.py" else name.rpartition(".")[0]
    names = [m for m in _import_names(origin, package) if m.startswith(within + ".") and _is_source(m, facts)]
    return names, facts


def _file_facts(module: str) -> list[str]:
    """[path, sha256 of the file, sha256 of its code]: what a remembered closure rests on, per module."""
    origin = _module_origin(module)
    return [str(origin), _file_sha256(origin), _own_source_hash(module)[1]]


def _import_names(origin: Path, package: str) -> list[str]:
    """Every name the file's import statements name, absolute (`from m import f` gives m and m.f).
    Parsing is most of what naming a kind's code costs, so the names are remembered across processes
    by the sha256 of the text (and the package its relative imports resolve against)."""
    source = origin.read_bytes()
    key = hashlib.sha256(package.encode() + b"\0" + source).hexdigest()
    if (names := HASH_CACHE.get_names(key)) is None:
        names = []
        for node in _statements(ast.parse(source, str(origin)).body):
            if isinstance(node, ast.Import):
                names += [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
                names += [base] + [f"{base}.{alias.name}" for alias in node.names]
        HASH_CACHE.put_names(key, names)
    return names


def _statements(body: list[ast.stmt]) -> Iterator[ast.AST]:
    """Every statement, nested ones included (an import is a statement: expressions need no walk)."""
    for node in body:
        yield node
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            yield from _statements(getattr(node, field, None) or [])


def _is_source(name: str, facts: _Facts) -> bool:
    """Whether `name` is a module or package (`from m import f` also yields `m.f`, which is none),
    found on disk: no module but the packages above it is imported. What telling rests on goes into
    `facts`."""
    parent, _, leaf = name.rpartition(".")
    if not parent:
        return importlib.util.find_spec(name) is not None
    if not _is_package(parent):   # a module (it stays one while its file exists), or none at all
        facts.exists.add(str(_ORIGINS[parent])) if parent in _ORIGINS else facts.unknown.add(parent)
        return False
    folder = _module_origin(parent).parent
    facts.exists.add(str(folder / "__init__.py"))
    facts.folders[str(folder)] = sorted(_modules_in(folder))
    return leaf in facts.folders[str(folder)]


def _modules_in(folder: Path | str) -> frozenset[str]:
    """The names of the modules and packages in a package's folder, listed once per process (until
    `clear_caches`): a closure asks whether a name is a module some thousand times, a few per folder."""
    folder = os.fspath(folder)
    if folder not in _FOLDERS:
        names = set()
        with os.scandir(folder) as entries:
            for entry in entries:
                if entry.name.endswith(".py") and entry.is_file():
                    names.add(entry.name[:-3])
                elif entry.is_dir() and os.path.isfile(os.path.join(entry.path, "__init__.py")):
                    names.add(entry.name)
        _FOLDERS[folder] = frozenset(names)
    return _FOLDERS[folder]


def _is_package(name: str) -> bool:
    try:
        return _module_origin(name).name == "__init__.py"
    except (MatrixError, ModuleNotFoundError):
        return False


def cache_generation() -> int:
    """Changes whenever the caches are cleared: what is derived from source text is stale then."""
    return _GENERATION[0]


def clear_caches() -> None:
    """Forget remembered hashes (for long-lived processes that watch code change)."""
    _GENERATION[0] += 1
    _IMPORTS.clear()
    _CLOSURES.clear()
    _SOURCE_FILES.clear()
    _CODE_HASHES.clear()
    _FILES_FOUND.clear()
    _ORIGINS.clear()
    _FOLDERS.clear()
    forget_file_hashes()
    _SOURCE_HASHES.clear()
