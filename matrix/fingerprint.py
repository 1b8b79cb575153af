"""Content fingerprints: of code (what implements a job kind) and of input files.

Code is fingerprinted by its source text without comments, docstrings and blank lines
(`code_text`), so editing a strategy's module changes the keys of that strategy's jobs and nothing
else, and rewording a comment or a docstring changes none; which modules a module imports is read
from its source, parsed once per text (the names are remembered across processes by its sha256),
and a whole closure is remembered with the file hashes and folder listings it was read from.
Files are hashed by content
(sha256), remembered by (path, size, mtime, inode) in the process and, for large files, across
processes, so an unchanged multi-GB bag is read once (both memories: matrix.hashcache).
"""
from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import math
import os
import stat
import sys
import time
import tokenize
from collections.abc import Iterable, Iterator
from io import BytesIO, StringIO
from pathlib import Path
from types import ModuleType
from typing import Any

from matrix.errors import MatrixError
from matrix.hashcache import HASH_CACHE

_FILE_HASHES: dict[tuple[str, int, int, int], str] = {}
_SOURCE_HASHES: dict[Any, str] = {}
_ORIGINS: dict[str, Path] = {}
_FOLDERS: dict[str, frozenset[str]] = {}
_GENERATION = [0]   # bumped by clear_caches: whatever was derived from source text is stale
CHUNK = 1 << 20
MAX_INPUT_FILES = 1_000_000   # files one input folder may hold (a bag folder holds a handful)
DEFAULT_MAX_INPUT_GB = 64.0   # bytes one input may hold, unless $MATRIX_MAX_INPUT_GB says otherwise


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
    _FILE_HASHES.clear()
    _SOURCE_HASHES.clear()


def hash_path(path: Path | str) -> str:
    """sha256 of a file, or of a folder's files (names and contents, sorted), e.g. a ROS2 bag.
    Only regular files and folders are inputs: a device, pipe, socket or a file of /proc, /sys or
    /dev is refused (reading one may never end). Hashes are remembered across processes (see
    HashCache), and a progress line is printed when hashing takes long."""
    path = Path(path)
    mode = _input_stat(path).st_mode
    if stat.S_ISDIR(mode):
        return _hash_folder_files(path, _folder_files(path))
    if not stat.S_ISREG(mode):
        raise MatrixError(f"input {shown_path(path)} is not a regular file or folder ({_file_type(mode)})")
    _check_size(path, path.stat().st_size, 1)
    with _HashProgress(path, path.stat().st_size) as progress:
        return _hash_file(path, progress)


def hash_files(folder: Path | str, files: Iterable[Path | str]) -> str:
    """sha256 of some files of a folder (names relative to it, and contents), as `hash_path` hashes a
    whole folder: for an input that reads only those (a dataset folder's index and the images it
    names), so that other files in the folder change nothing."""
    folder = Path(folder)
    listed = sorted({Path(file) for file in files}, key=lambda file: file.relative_to(folder).parts)
    return _hash_folder_files(folder, [(file, _input_stat(file).st_size) for file in listed])


def _hash_folder_files(folder: Path, files: list[tuple[Path, int]]) -> str:
    _check_size(folder, sum(size for _, size in files), len(files))
    with _HashProgress(folder, sum(size for _, size in files)) as progress:
        digest = hashlib.sha256()
        for file, _ in files:
            digest.update(f"{file.relative_to(folder).as_posix()}:{_hash_file(file, progress)}\n".encode())
    return digest.hexdigest()


_PSEUDO_ROOTS = ("/proc", "/sys", "/dev")


def _max_input_bytes() -> float:
    try:
        gigabytes = float(os.environ.get("MATRIX_MAX_INPUT_GB") or DEFAULT_MAX_INPUT_GB)
    except ValueError:
        gigabytes = math.nan
    if not (math.isfinite(gigabytes) and gigabytes > 0):   # nan turned the limit off, -1 read as a limit
        raise MatrixError(f"MATRIX_MAX_INPUT_GB={os.environ['MATRIX_MAX_INPUT_GB']!r} is not a positive number "
                          "(gigabytes one input may hold)")
    return gigabytes * 1e9


def _check_size(path: Path, size: int, files: int) -> None:
    """Hashing is bounded: an input larger than the limit is refused before it is read."""
    limit = _max_input_bytes()
    if size > limit:
        raise MatrixError(f"input {shown_path(path)} holds {size / 1e9:.1f} GB in {files} file(s), more than the "
                          f"{limit / 1e9:g} GB an input may hold; name the recording itself (not a folder above "
                          "it), or raise the limit with MATRIX_MAX_INPUT_GB")


def shown_path(path: Path, limit: int = 120) -> str:
    text = str(path)
    return text if len(text) <= limit else f"{text[:limit // 2]}...{text[-limit // 2:]} ({len(text)} characters)"


def _input_stat(path: Path) -> os.stat_result:
    try:
        result = path.stat()
        resolved = path.resolve()
    except (OSError, ValueError, RuntimeError) as error:
        raise MatrixError(f"input {shown_path(path)} cannot be read: {getattr(error, 'strerror', None) or error}") from None
    if root := system_root(resolved):
        raise MatrixError(f"input {shown_path(path)} is a system file (below {root}), not data; "
                          "name a bag, a dataset folder or a CSV")
    return result


def system_root(resolved: Path) -> Path | None:
    """The pseudo-file-system root (/proc, /sys, /dev) a resolved path is below, or None."""
    return next((root for root in map(Path, _PSEUDO_ROOTS) if resolved == root or root in resolved.parents), None)


def _refuse_system_folder(folder: Path, path: Path) -> None:
    if root := system_root(path.resolve()):
        raise MatrixError(f"input folder {shown_path(folder)} holds {shown_path(path)}, which is a system folder "
                          f"(below {root}), not data; name the recording itself (not a folder above it)")


def _file_type(mode: int) -> str:
    for test, name in ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISFIFO, "a pipe"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a file"


def _folder_files(folder: Path) -> list[tuple[Path, int]]:
    """(file, size) of every regular file below `folder`, sorted as before (by path parts), so keys
    stay the same. Symbolic links to files count as files, links to folders are not followed (as
    `rglob` did); a device, pipe or socket, or an unreadable folder, is an error naming it, found
    before anything is hashed. A system folder (/proc, /sys, /dev) is refused when it is met, not when
    the walk reaches a device inside it, so `/` fails at once whatever else it holds."""
    found: list[tuple[Path, int]] = []
    pending = [folder]
    while pending:
        current = pending.pop()
        try:
            entries = sorted(os.scandir(current), key=lambda e: e.name, reverse=True)
        except OSError as error:
            raise MatrixError(f"input folder {shown_path(Path(current))} cannot be read: {error.strerror}") from None
        for entry in entries:
            path = Path(entry.path)
            try:
                if entry.is_dir(follow_symlinks=False):
                    _refuse_system_folder(folder, path)
                    pending.append(path)
                    continue
                info = path.stat() if entry.is_symlink() else entry.stat(follow_symlinks=False)
                target = path.resolve() if entry.is_symlink() else None
            except FileNotFoundError:   # a broken link: nothing to read, skipped as before
                continue
            except (OSError, RuntimeError) as error:   # RuntimeError: a loop of links
                raise MatrixError(f"input {shown_path(path)} cannot be read: "
                                  f"{getattr(error, 'strerror', None) or error}") from None
            if target is not None and (root := system_root(target)):
                raise MatrixError(f"input folder {shown_path(folder)} holds {shown_path(path)}, a link to "
                                  f"{shown_path(target)}: a system file (below {root}), not data; remove the link")
            if stat.S_ISREG(info.st_mode):
                found.append((path, info.st_size))
                if len(found) > MAX_INPUT_FILES:
                    raise MatrixError(f"input folder {shown_path(folder)} holds more than {MAX_INPUT_FILES:,} "
                                      "files; name the recording itself (not a folder above it)")
            elif not stat.S_ISDIR(info.st_mode):   # (a link to a folder is skipped, as before)
                raise MatrixError(f"input folder {shown_path(folder)} holds {shown_path(path)}, which is "
                                  f"{_file_type(info.st_mode)}, not data")
    return sorted(found)


def _hash_file(path: Path, progress: _HashProgress | None = None) -> str:
    try:
        info = path.stat()
        marker = (str(path.resolve()), info.st_size, info.st_mtime_ns, info.st_ino)
        if marker not in _FILE_HASHES:
            _FILE_HASHES[marker] = HASH_CACHE.get(marker) or HASH_CACHE.put(marker, _read_hash(path, progress))
        elif progress is not None:
            progress.advance(info.st_size)
        return _FILE_HASHES[marker]
    except OSError as error:
        raise MatrixError(f"input {shown_path(path)} cannot be read: {error.strerror or error}") from None


def _read_hash(path: Path, progress: _HashProgress | None) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while chunk := handle.read(CHUNK):
            digest.update(chunk)
            if progress is not None:
                progress.advance(len(chunk))
    return digest.hexdigest()


class _HashProgress:
    """Prints `hashing PATH: 1.2 of 5.9 GB` to stderr every few seconds once hashing has taken longer
    than `after_s` (inputs seen before come from the cache and take no time)."""

    def __init__(self, path: Path, total: int, after_s: float = 2.0, every_s: float = 5.0):
        self.path, self.total, self.done = path, total, 0
        self.started = time.monotonic()
        self.next_print, self.every_s, self.printed = self.started + after_s, every_s, False

    def __enter__(self) -> _HashProgress:
        return self

    def advance(self, n: int) -> None:
        self.done += n
        now = time.monotonic()
        if now >= self.next_print:
            self.next_print, self.printed = now + self.every_s, True
            self._print(f"hashing input {shown_path(self.path, 80)}: {_size(self.done)} of {_size(self.total)} "
                        f"({now - self.started:.0f} s; remembered afterwards)")

    def __exit__(self, *exc) -> None:
        if self.printed and exc[0] is None:
            self._print(f"hashed input {shown_path(self.path, 80)}: {_size(self.total)} in "
                        f"{time.monotonic() - self.started:.0f} s")

    @staticmethod
    def _print(line: str) -> None:
        print(line, file=sys.stderr, flush=True)


def _size(n: int) -> str:
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.1f} MB"
