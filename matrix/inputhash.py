"""Content fingerprints of input files: a recording, a dataset folder, a CSV.

Files are hashed by content (sha256), remembered by (path, size, mtime, inode) in the process and,
for large files, across processes, so an unchanged multi-GB bag is read once (both memories:
matrix.hashcache). Only regular files and folders are inputs, and their size is bounded.
"""
from __future__ import annotations

import hashlib
import math
import os
import stat
import sys
import time
from collections.abc import Iterable
from pathlib import Path

from matrix.errors import MatrixError
from matrix.hashcache import HASH_CACHE

_FILE_HASHES: dict[tuple[str, int, int, int], str] = {}
CHUNK = 1 << 20
MAX_INPUT_FILES = 1_000_000   # files one input folder may hold (a bag folder holds a handful)
DEFAULT_MAX_INPUT_GB = 64.0   # bytes one input may hold, unless $MATRIX_MAX_INPUT_GB says otherwise


def forget_file_hashes() -> None:
    """Forget the hashes remembered in this process (files are hashed again, or read from HashCache)."""
    _FILE_HASHES.clear()


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
