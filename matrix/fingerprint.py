"""Content fingerprints: of code (what implements a job kind) and of input files.

Code is fingerprinted by its source text, so editing a strategy's module changes the keys of that
strategy's jobs and nothing else. Files are hashed by content (sha256), remembered by
(path, size, mtime) so an unchanged multi-GB bag is read once per process.
"""
from __future__ import annotations

import ast
import hashlib
import importlib.util
import os
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

from matrix.errors import MatrixError

_FILE_HASHES: dict[tuple[str, int, int], str] = {}
_SOURCE_HASHES: dict[Any, str] = {}
_GENERATION = [0]   # bumped by clear_caches: whatever was derived from source text is stale
CHUNK = 1 << 20


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
        _SOURCE_HASHES[ident] = hashlib.sha256(_module_origin(module).read_bytes()).hexdigest()
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
        _SOURCE_HASHES[ident] = hashlib.sha256(_module_files_text(_module_origin(ident)).encode()).hexdigest()
    return ident, _SOURCE_HASHES[ident]


def _module_origin(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        raise MatrixError(f"cannot find module {name!r} to fingerprint its code")
    return Path(spec.origin)


def _module_files_text(origin: Path) -> str:
    """A module's text; for a package (`__init__.py`), every .py file below it, in a fixed order."""
    if origin.name != "__init__.py":
        return origin.read_text(encoding="utf-8")
    files = sorted(origin.parent.rglob("*.py"))
    return "".join(f"# {f.relative_to(origin.parent)}\n{f.read_text(encoding='utf-8')}" for f in files)


def module_closure(name: str, within: str, exclude: Iterable[str] = ()) -> list[str]:
    """`name` and the modules below package `within` that it imports, transitively (imports inside
    functions included), found by reading the source: nothing is imported, so a domain can name the
    code behind a job without loading the heavy libraries that code uses. Modules in `exclude` (and
    what only they import) are left out: shared code a kind fingerprints anyway."""
    found: list[str] = []
    pending, skip = [name], set(exclude)
    while pending:
        module = pending.pop()
        if module not in found and module not in skip:
            found.append(module)
            pending += _imported_modules(module, within)
    return found


_IMPORTS: dict[tuple, list[str]] = {}


def _imported_modules(name: str, within: str) -> list[str]:
    """The modules below package `within` that `name`'s source imports (read once per process,
    until `clear_caches`)."""
    key = (_GENERATION[0], name, within)
    if key not in _IMPORTS:
        _IMPORTS[key] = _read_imports(name, within)
    return _IMPORTS[key]


def _read_imports(name: str, within: str) -> list[str]:
    origin = _module_origin(name)
    package = name if origin.name == "__init__.py" else name.rpartition(".")[0]
    modules = []
    for node in ast.walk(ast.parse(origin.read_text(encoding="utf-8"), str(origin))):
        if isinstance(node, ast.Import):
            modules += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            modules += [base] + [f"{base}.{alias.name}" for alias in node.names]
    return [m for m in modules if m.startswith(within + ".") and _is_source(m)]


def _is_source(name: str) -> bool:
    """Whether `name` is a module or package (`from m import f` also yields `m.f`, which is none),
    found on disk: no module but the packages above it is imported."""
    parent, _, leaf = name.rpartition(".")
    if not parent:
        return importlib.util.find_spec(name) is not None
    folder = _module_origin(parent).parent if _is_package(parent) else None
    return folder is not None and ((folder / f"{leaf}.py").is_file() or (folder / leaf / "__init__.py").is_file())


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
    _FILE_HASHES.clear()
    _SOURCE_HASHES.clear()


def hash_path(path: Path | str) -> str:
    """sha256 of a file, or of a folder's files (names and contents, sorted), e.g. a ROS2 bag."""
    path = Path(path)
    if path.is_dir():
        digest = hashlib.sha256()
        for file in sorted(p for p in path.rglob("*") if p.is_file()):
            digest.update(f"{file.relative_to(path).as_posix()}:{_hash_file(file)}\n".encode())
        return digest.hexdigest()
    if not path.is_file():
        raise MatrixError(f"input file {path} does not exist")
    return _hash_file(path)


def _hash_file(path: Path) -> str:
    stat = path.stat()
    marker = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if marker not in _FILE_HASHES:
        digest = hashlib.sha256()
        with open(path, "rb") as handle:
            while chunk := handle.read(CHUNK):
                digest.update(chunk)
        _FILE_HASHES[marker] = digest.hexdigest()
    return _FILE_HASHES[marker]


def host_fingerprint_cpu() -> dict[str, Any]:
    """CPU model and core count (generic part of a host fingerprint; the domain adds GPUs)."""
    model = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        import platform
        model = platform.processor()
    return {"cpu": model, "cores": os.cpu_count()}
