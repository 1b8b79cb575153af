"""Code users write: a class (or any object) named `file.py:Name` or `module:Name`.

    brain_class = load_object("brains/mine.py:MyBrain", base=recipe_folder)
    digest = source_hash("brains/mine.py:MyBrain", base=recipe_folder)   # for job keys, reads files only

A file is read relative to `base` (the recipe's folder, or the current one on the command line), and
its folder goes on `sys.path` as when Python runs a script, so the modules beside it import. A
module is imported by name (with `base` on `sys.path`). `Name` may be dotted (`Outer.Inner`).
One process loads many users' code (a pool worker runs job after job): loading from one folder takes
the other user folders off `sys.path` and the modules imported from them out of `sys.modules`, so two
networks that each import their own `helpers.py` (or a package of the same name) never share one.

Whatever goes wrong is a `UserCodeError` of one line that names the file and line: a missing file,
a syntax error, an exception while the file is imported (the line in the user's file it came from),
a name the file does not define (with "did you mean" and what it does define).

`source_hash` is the sha256 of the file's code (its text without comments, docstrings and blank
lines) and of the user's own modules it imports (those found beside it, or in its package for a file
in one, followed transitively; `import x`, `from x import y`, `from .x import y`, `from ..x import y`,
at any depth of the file), so editing any of them changes the key of the jobs that run the code.
Nothing is imported to compute it: planning never runs user code.
"""
from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.util
import inspect
import os.path
import sys
import sysconfig
import textwrap
import traceback
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matrix.errors import did_you_mean
from matrix.fingerprint import source_code_text
from matrix.jobs import InputFile
from pilotlab.errors import PilotlabError


PILOTLAB = str(Path(__file__).resolve().parent) + os.sep   # frames of pilotlab itself are not the user's
STDLIB = sysconfig.get_paths()["stdlib"] + os.sep            # nor Python's own (argparse, when a module exits)


class UserCodeError(PilotlabError):
    """The user's code cannot be loaded; the message names the file and line."""


@dataclass(frozen=True)
class UserCode:
    spec: str              # as the user wrote it
    file: Path | None      # the file named (file.py:Name), absolute
    module: str | None     # the module named (module:Name)
    name: str              # the object inside it

    @property
    def where(self) -> str:
        return str(self.file) if self.file is not None else self.module


def parse(spec: str, base: Path) -> UserCode:
    """What `spec` names; the file must exist."""
    target, colon, name = str(spec).rpartition(":")
    if not colon or not target or not all(part.isidentifier() for part in name.split(".")):
        raise UserCodeError(f"{spec!r}: name user code as file.py:Class or module:Class")
    if target.endswith(".py") or "/" in target or "\\" in target:
        file = Path(target).expanduser()
        file = (file if file.is_absolute() else Path(base) / file).resolve()
        if not file.is_file():
            raise UserCodeError(f"{target}: no such file (looked for {file}; a relative path is relative to "
                                f"{Path(base).resolve()})")
        return UserCode(str(spec), file, None, name)
    if not all(part.isidentifier() for part in target.split(".")):
        raise UserCodeError(f"{spec!r}: {target!r} is neither a .py file nor a module name")
    return UserCode(str(spec), None, target, name)


def load_object(spec: str, base: Path) -> object:
    """The object `spec` names (see the module docstring); imports the user's file or module."""
    code = parse(spec, base)
    module = _import_file(code) if code.file is not None else _import_module(code, Path(base))
    found: object = module
    for i, part in enumerate(code.name.split(".")):
        if not hasattr(found, part):
            defined = sorted(n for n in vars(found) if not n.startswith("_") and isinstance(vars(found)[n], type))
            inside = code.where if i == 0 else f"{code.where}:{'.'.join(code.name.split('.')[:i])}"
            raise UserCodeError(f"{inside} has no {part!r}{did_you_mean(part, defined)}; it defines: "
                                f"{', '.join(defined) or '(no classes)'}")
        found = getattr(found, part)
    return found


_ROOTS: dict[str, set[str]] = {}   # a user folder put on sys.path -> the modules imported from it
_ADDED: set[str] = set()            # ... of which these were not on sys.path before


@contextmanager
def _from_root(root: Path) -> Iterator[None]:
    """Imports inside resolve in user folder `root` alone (see the module docstring); the modules they
    load from it are noted, to be dropped when another user folder's code is loaded."""
    folder = str(root)
    for other in [other for other in _ROOTS if other != folder]:
        for name in _ROOTS.pop(other):
            sys.modules.pop(name, None)
        if other in _ADDED:
            _ADDED.discard(other)
            while other in sys.path:
                sys.path.remove(other)
    if folder not in sys.path:
        sys.path.insert(0, folder)
        _ADDED.add(folder)
    before = set(sys.modules)
    try:
        yield
    finally:
        _ROOTS.setdefault(folder, set()).update(
            name for name in set(sys.modules) - before
            if name.partition(".")[0] not in before and _users(sys.modules.get(name), root))


def _users(module: object, root: Path) -> bool:
    """Whether `module` is a user's file in `root` (not an installed package: a project's own .venv may lie
    inside it, and an installed package is never taken out of sys.modules)."""
    file = getattr(module, "__file__", None)
    if not file:
        return False
    path = Path(file).resolve()
    return path.is_relative_to(root) and not any(path.is_relative_to(p) for p in _INSTALLED)


_INSTALLED = {Path(sysconfig.get_paths()[k]).resolve() for k in ("stdlib", "platstdlib", "purelib", "platlib")}


def _import_file(code: UserCode) -> object:
    if (package := _in_package(code.file)) is not None:   # its relative imports need its package
        root, dotted = package
        module = _import_module(UserCode(code.spec, None, dotted, code.name), root)
        if Path(getattr(module, "__file__", "") or "").resolve() != code.file:
            raise UserCodeError(f"{code.spec}: another module {dotted!r} is loaded already (from "
                                f"{getattr(module, '__file__', None)}); rename one of the two packages")
        return module
    with _from_root(code.file.parent):
        return _exec_file(code)


def _exec_file(code: UserCode) -> object:
    digest = hashlib.sha256(str(code.file).encode()).hexdigest()[:12]
    name = f"pilotlab_user_{code.file.stem}_{digest}"     # unique per path: two mine.py never clash
    spec = importlib.util.spec_from_file_location(name, code.file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        with _own_argv(code.file):
            spec.loader.exec_module(module)
    except BaseException as error:
        sys.modules.pop(name, None)
        raise _import_error(code, error) from None
    return module


@contextmanager
def _own_argv(file: Path) -> Iterator[None]:
    """sys.argv as if `file` ran alone: a module that parses the command line when imported (argparse at
    the top of a brain) sees no arguments, not pilotlab's, and cannot reject them in pilotlab's name."""
    saved, sys.argv = sys.argv, [str(file)]
    try:
        yield
    finally:
        sys.argv = saved


def _in_package(file: Path) -> tuple[Path, str] | None:
    """(the folder above its top package, its dotted name) for a file in a package (a folder holding
    __init__.py), so that it imports as Python would import it from there; None for a plain file."""
    packages = _package_folders(file)
    if not packages or not file.stem.isidentifier():
        return None
    names = [folder.name for folder in reversed(packages)] + ([] if file.name == "__init__.py" else [file.stem])
    return packages[-1].parent, ".".join(names)


def _package_folders(file: Path) -> list[Path]:
    """The package folders `file` is in, innermost first: each holds __init__.py and is named like a module."""
    folders, folder = [], file.parent
    while (folder / "__init__.py").is_file() and folder.name.isidentifier() and folder != folder.parent:
        folders.append(folder)
        folder = folder.parent
    return folders


def _import_module(code: UserCode, base: Path) -> object:
    try:
        with _from_root(Path(base).resolve()), _own_argv(Path(code.module)):
            return importlib.import_module(code.module)
    except ModuleNotFoundError as error:
        if error.name is not None and (code.module == error.name or code.module.startswith(error.name + ".")):
            raise UserCodeError(f"{code.spec}: no module {code.module!r} (looked on sys.path and in {base})") from None
        raise _import_error(code, error) from None
    except BaseException as error:
        raise _import_error(code, error) from None


def _import_error(code: UserCode, error: BaseException) -> UserCodeError:
    if isinstance(error, KeyboardInterrupt):
        raise error
    if isinstance(error, SystemExit):
        return UserCodeError(f"{_place(error, code.where)}: the module called exit({error.code!r}) while being imported (importing "
                             f"{code.spec}); put what runs it as a script under `if __name__ == \"__main__\":`")
    return UserCodeError(error_line(error, code.where) + f" (importing {code.spec})")


def returned_at(function: Callable, where: str) -> str:
    """Where the user's `function` returned a wrong value (the value has no line of its own): `file:line` of
    its one return statement; of its def, saying its returns' lines when it has several, or that it has
    none (so it returned None); else `where`."""
    try:
        lines, first = inspect.getsourcelines(function)
        file = inspect.getsourcefile(function)
        tree = ast.parse(textwrap.dedent("".join(lines)))
    except (TypeError, OSError, SyntaxError):
        return where
    returns = sorted(first - 1 + line for line in _return_lines(tree.body[0])) if tree.body else []
    if len(returns) == 1:
        return f"{file}:{returns[0]}"
    said = f"returns at lines {', '.join(map(str, returns))}" if returns else "no return statement: it returns None"
    return f"{file}:{first} ({said})"


def _return_lines(function: ast.AST) -> list[int]:
    """The lines of `function`'s own return statements (not those of functions or classes inside it)."""
    found, todo = [], list(ast.iter_child_nodes(function))
    while todo:
        node = todo.pop()
        if isinstance(node, ast.Return):
            found.append(node.lineno)
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            todo.extend(ast.iter_child_nodes(node))
    return found


def error_line(error: BaseException, where: str) -> str:
    """`file:line: Type: message` for an exception raised in the user's code: the line of the user's
    file it came from (the last frame outside Python's machinery and installed packages), else `where`
    (nothing where it is "")."""
    if isinstance(error, SyntaxError):
        text = (error.text or "").strip()
        return f"{error.filename}:{error.lineno}: syntax error: {error.msg}" + (f": {text}" if text else "")
    message, place = str(error).splitlines()[0] if str(error) else "", _place(error, where)
    return (f"{place}: " if place else "") + type(error).__name__ + (f": {message}" if message else "")


def _place(error: BaseException, where: str) -> str:
    """`file:line` of the user's frame an exception came from (the last outside Python's machinery and
    installed packages), else `where`."""
    mine = [f for f in traceback.extract_tb(error.__traceback__) if not _is_library(f.filename)]
    return f"{mine[-1].filename}:{mine[-1].lineno}" if mine else where


def error_place(error: BaseException) -> str:
    """`file:line` of the user's frame `error` came from, else ""."""
    return _place(error, "")


def _is_library(filename: str) -> bool:
    """Frames of Python's import machinery, installed packages and pilotlab: not the user's."""
    return filename.startswith(("<frozen", PILOTLAB, STDLIB)) or "site-packages" in filename


def check_syntax(file: Path) -> ast.Module:
    """`file`'s syntax tree; a UserCodeError naming the line when it does not parse (nothing is run)."""
    try:
        return ast.parse(Path(file).read_bytes(), str(file))
    except SyntaxError as error:
        raise UserCodeError(error_line(error, str(file))) from None
    except ValueError as error:   # a NUL byte
        raise UserCodeError(f"{file}: not Python source ({error})") from None


def check_source(spec: str, base: Path, options: Mapping[str, Any] | None = None) -> None:
    """At plan, from the source alone (nothing is run): the file `spec` names parses, defines the name
    at its top level, and that class's __init__ takes `options`, as loading would find (a typo then
    fails the plan, not a job in the run). What the source cannot say is left to loading: a module
    (not a file), a star import, a module __getattr__, an inherited __init__, **kwargs."""
    code = parse(spec, base)
    if code.file is None:
        return
    defined = _top_level(check_syntax(code.file).body)
    top = code.name.split(".")[0]
    if defined is None or "__getattr__" in defined or top in defined and not isinstance(defined[top], ast.ClassDef):
        return   # made at run time (a star import, a module __getattr__), or not a class: loading says
    if top not in defined:
        classes = sorted(n for n, node in defined.items() if isinstance(node, ast.ClassDef) and not n.startswith("_"))
        raise UserCodeError(f"{code.where} has no {top!r}{did_you_mean(top, classes)}; it defines: "
                            f"{', '.join(classes) or '(no classes)'}")
    if options is not None and "." not in code.name:
        _check_options(defined[top], options)


def _top_level(body: list[ast.stmt]) -> dict[str, ast.AST] | None:
    """Name -> node of what a module's statements define (in its top-level if/try/with blocks too);
    None after a star import (it may define anything)."""
    found: dict[str, ast.AST] = {}
    for node in body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            found[node.name] = node
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            if any(alias.name == "*" for alias in node.names):
                return None
            found.update({alias.asname or alias.name.split(".")[0]: node for alias in node.names})
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            found.update({n.id: node for target in targets for n in ast.walk(target) if isinstance(n, ast.Name)})
        else:
            for block in ("body", "orelse", "finalbody", "handlers"):
                inner = _top_level([s for s in getattr(node, block, []) if isinstance(s, ast.stmt)]
                                   + [s for h in getattr(node, block, []) if isinstance(h, ast.excepthandler)
                                      for s in h.body])
                if inner is None:
                    return None
                found.update(inner)
    return found


def _check_options(cls: ast.ClassDef, options: Mapping[str, Any]) -> None:
    init = next((n for n in cls.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"), None)
    if init is None or init.args.kwarg is not None:
        return
    args = init.args
    positional = [a.arg for a in args.posonlyargs + args.args][1:]
    takes = positional + [a.arg for a in args.kwonlyargs]
    if problem := options_not_taken(cls.name, takes, options):
        raise UserCodeError(problem)
    # those with no default must be given (outside test: a missing one was found only when the job ran)
    required = positional[:len(positional) - len(args.defaults)] + [
        a.arg for a, default in zip(args.kwonlyargs, args.kw_defaults) if default is None]
    if missing := [name for name in required if name not in options]:
        raise UserCodeError(f"options: {cls.name}({', '.join(takes)}) needs {', '.join(missing)}, which has no "
                            f"default: give {'it' if len(missing) == 1 else 'them'} under options")


def options_not_taken(name: str, takes: list[str], options: Mapping[str, Any]) -> str | None:
    """What is wrong with giving `options` to the class `name` whose constructor takes `takes` (None: nothing)."""
    if unknown := [option for option in options if option not in takes]:
        guesses = "".join(did_you_mean(option, takes) for option in unknown)
        return f"options: {name}({', '.join(takes)}) does not take {', '.join(unknown)}{guesses}"
    return None


# --- the source hash -------------------------------------------------------------------------------

def source_files(spec: str, base: Path) -> list[Path]:
    """The file `spec` names (for a module: its file), then the user's modules it imports, transitively
    (sorted). An installed module (found on sys.path, not in `base`) is taken alone: it is not the user's to edit."""
    code = parse(spec, base)
    if code.file is not None:   # a file in a package imports as part of it: from the folder above the top package
        first, roots = code.file, [] if (package := _in_package(code.file)) is None else [package[0]]
    else:
        first, root = _module_file(code, Path(base))
        if root != Path(base).resolve():
            return [first]
        roots = [root]
    seen: dict[Path, None] = {}
    pending = [first]
    while pending:
        file = pending.pop()
        if file not in seen:
            seen[file] = None
            pending += _local_imports(file, [file.parent, *roots]) + _package_inits(file)
    return [first, *sorted(set(seen) - {first})]


def _package_inits(file: Path) -> list[Path]:
    """The __init__.py files that run when `file` is imported as part of its package (see _in_package)."""
    return [(folder / "__init__.py").resolve() for folder in _package_folders(file)]


def source_hash(spec: str, base: Path) -> str:
    """sha256 over the code of `source_files(spec, base)` (their text without comments, docstrings and
    blank lines: matrix.fingerprint.code_text) and their names (relative to their common folder)."""
    files = source_files(spec, base)
    return _combined_hash(files, [_code_text(file) for file in files])


def base_of(spec: str, file: Path) -> Path:
    """A folder that `spec` is read relative to and names `file` from (the file of its `source_input`):
    a job keeps the spec as written and finds its folder again from its input, whose path is no part of
    its key, so a project moved or cloned elsewhere keeps the results its user code made."""
    target, file = spec.rpartition(":")[0], Path(file).resolve()
    if target.endswith(".py") or "/" in target or "\\" in target:
        return next((folder for folder in file.parents if (folder / Path(target).expanduser()).resolve() == file),
                    file.parent)
    depth = len(target.split(".")) + (file.name == "__init__.py")   # a package's module, or the package
    return file.parents[min(depth, len(file.parents)) - 1]


def source_input(spec: str, base: Path) -> InputFile:
    """The job input of the user's code `spec`: its file, `source_hash`, and each file's own hash (named
    relative to `base`, the recipe's folder), so that `plan` names the module that changed."""
    files = source_files(spec, base)
    texts = [_code_text(file) for file in files]     # each file read once, for both hashes
    parts = tuple((os.path.relpath(file, base), hashlib.sha256(text.encode()).hexdigest())
                  for file, text in zip(files, texts))
    return InputFile(str(files[0]), _combined_hash(files, texts), parts)


def _code_text(file: Path) -> str:
    return source_code_text(_read(file))   # read by its coding line, as Python does


def _combined_hash(files: list[Path], texts: list[str]) -> str:
    root = Path(os.path.commonpath([str(f.parent) for f in files]))
    digest = hashlib.sha256()
    for file, text in zip(files, texts):
        digest.update(f"# {file.relative_to(root).as_posix()}\n".encode())
        digest.update(text.encode())
    return digest.hexdigest()


def _read(file: Path) -> bytes:
    try:
        return file.read_bytes()
    except OSError as error:
        raise UserCodeError(f"{file}: cannot read it ({error.strerror or error}); it is your code or a module "
                            "it imports, and goes into the job's key: make it readable") from None


def _module_file(code: UserCode, base: Path) -> tuple[Path, Path]:
    """(the module's file, the folder its top-level package is in)."""
    for folder in [base, *map(Path, sys.path)]:
        for candidate in _candidates(folder, code.module):
            if candidate.is_file():
                return candidate.resolve(), folder.resolve()
    raise UserCodeError(f"{code.spec}: no module {code.module!r} found as a file (looked in {base} and on sys.path)")


def _candidates(folder: Path, module: str) -> list[Path]:
    path = Path(folder, *module.split("."))
    return [path.with_suffix(".py"), path / "__init__.py"]


def _imported_names(tree: ast.AST) -> list[tuple[int, str]]:
    """(level, dotted name) of what a module imports: `import a.b` gives (0, a.b); `from a import b` gives
    (0, a) and (0, a.b) (b may be a module); `from ..x import b` (level 2) gives (2, x) and (2, x.b), and
    `from . import b` (1, b): relative to the folder `level - 1` above the file's own."""
    names: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [(0, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            prefix = f"{node.module}." if node.module else ""
            names += [(node.level, node.module)] if node.module else []
            names += [(node.level, prefix + alias.name) for alias in node.names if alias.name != "*"]
    return names


def _local_imports(file: Path, roots: list[Path]) -> list[Path]:
    """Files under `roots` that `file` imports (and the packages' __init__.py on the way), its relative
    imports resolved against its own folder; a file that does not parse imports nothing here (loading
    it will say why)."""
    try:
        tree = ast.parse(file.read_bytes(), str(file))   # bytes: decoded by the file's coding line
    except (SyntaxError, UnicodeDecodeError, ValueError, OSError):   # (an unreadable one: source_hash says)
        return []
    found = []
    for level, name in _imported_names(tree):
        parts = name.split(".")
        for root in roots if level == 0 else _relative_root(file, level):
            for depth in range(1, len(parts) + 1):
                found += [c.resolve() for c in _candidates(root, ".".join(parts[:depth])) if c.is_file()]
    return list(dict.fromkeys(found))


def _relative_root(file: Path, level: int) -> list[Path]:
    """The folder a relative import of `level` dots in `file` resolves against ([] above the filesystem's root)."""
    folders = [file.parent, *file.parent.parents]
    return folders[level - 1:level]
