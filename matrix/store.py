"""The job store: content-addressed folders, atomic writes, per-job locks.

    <root>/jobs/<key[:2]>/<key>/   spec.json, result.json, log.txt, artifacts/, verified.json
    <root>/failed/<key>.json       the last failure of a job (error, traceback, log tail)
    <root>/locks/<key>.lock        held (flock) by the process running the job
    <root>/locks/runs.lock         held shared by every run while it runs, exclusively by gc
    <root>/tmp/                    jobs in flight; renamed into jobs/ when their result is written
    <root>/recipes/<name>.json     the job names and specs of a recipe's last run (plan's reasons, status
                                   --times), and of each job it had yet to run, the version before
    <root>/cache/                  scratch shared by jobs (for example decoded frames)

A job is done exactly when `jobs/<key>/result.json` exists: the folder appears by one rename, so a
killed run loses only the jobs it had in flight, and readers never see half a job.

result.json lists every artifact with its size and sha256 ("manifest"). Checking that an entry is
intact costs a stat per file: verified.json keeps (size, mtime, inode, ctime) of each file as last
hashed, and a file whose stat differs is hashed again; a job about to read its dependencies' artifacts
hashes them in full (`outputs_state(..., full=True)`), once per run: verified.json names the run that
last hashed every file in full (the one that made them, at their commit), and within that run the stat
check stands for it (the study's jobs hashed 14 GB of their dependencies, the training frames 48 times
over). A file that no longer has its sha256 makes the entry "changed": it is never read, and the next
run rebuilds it.
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import re
import shutil
import tempfile
import time
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from matrix.errors import MatrixError

RESULT, SPEC, LOG, ARTIFACTS = "result.json", "spec.json", "log.txt", "artifacts"
VERIFIED = "verified.json"
RUNS_LOCK = "runs.lock"
_KEY, _SHARD = re.compile(r"[0-9a-f]{64}"), re.compile(r"[0-9a-f]{2}")
INTACT, MISSING, CHANGED = "", "missing", "changed"
# verified.json's record of the file last found changed: a name no artifact has (theirs are relative paths)
CHANGED_MARK = "/changed"
RUN_MARK = "/hashed in full by run"   # in verified.json: the run that last hashed every file in full


class StoreError(MatrixError):
    pass


def write_json_atomic(path: Path, value: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    with os.fdopen(fd, "w", encoding="utf-8") as handle:
        json.dump(value, handle, indent=1, sort_keys=True)
    os.replace(tmp, path)


def result_token(result: dict) -> str:
    """Names one stored result (a rerun of the same job writes another): what a forced run means to
    replace, so that it reruns the job once, not again after another run already replaced it."""
    return hashlib.sha256(json.dumps(result, sort_keys=True).encode()).hexdigest()


def outputs_token(result: dict) -> str:
    """Names what a stored result gives the jobs that stand on it (its value and its files), not when or
    how long it ran: a job rebuilt with the same outputs leaves them fresh. Written into the result when
    it is committed (`outputs`, without its kind's measured keys); worked out for a result from before."""
    return result.get("outputs") or outputs_hash(result)


def outputs_hash(result: dict, measured: Collection[str] = ()) -> str:
    """sha256 of the result's status, value and file manifest, leaving out the value's `measured` keys at any
    depth (how long the run took: a rerun differs there, whatever it made)."""
    outputs = {"status": result.get("status"), "value": without_keys(result.get("value"), frozenset(measured)),
               "manifest": result.get("manifest")}
    return hashlib.sha256(json.dumps(outputs, sort_keys=True).encode()).hexdigest()


def without_keys(value: Any, keys: frozenset[str]) -> Any:
    """JSON-like `value` less the entries named `keys`, at any depth (measured figures, wall times)."""
    if not keys:
        return value
    if isinstance(value, dict):
        return {k: without_keys(v, keys) for k, v in value.items() if k not in keys}
    return [without_keys(v, keys) for v in value] if isinstance(value, list) else value


def read_json(path: Path) -> Any | None:
    """The JSON in `path`, or None when it is missing or unreadable (a corrupt file is not a result)."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


class Store:
    def __init__(self, root: Path | str):
        self.root = Path(root)

    def __repr__(self) -> str:
        return f"Store({str(self.root)!r})"

    # --- layout -------------------------------------------------------------------------------
    def job_dir(self, key: str) -> Path:
        return self.root / "jobs" / key[:2] / key

    def artifacts(self, key: str) -> Path:
        return self.job_dir(key) / ARTIFACTS

    def failed_path(self, key: str) -> Path:
        return self.root / "failed" / f"{key}.json"

    def recipe_path(self, name: str) -> Path:
        return self.root / "recipes" / f"{name}.json"

    @property
    def cache(self) -> Path:
        path = self.root / "cache"
        path.mkdir(parents=True, exist_ok=True)
        return path

    # --- results ------------------------------------------------------------------------------
    def result(self, key: str) -> dict | None:
        """The stored result of a finished job, or None (missing or corrupt)."""
        result = read_json(self.job_dir(key) / RESULT)
        return result if isinstance(result, dict) and "status" in result else None

    def spec(self, key: str) -> dict | None:
        return read_json(self.job_dir(key) / SPEC)

    def outputs_intact(self, key: str, result: dict) -> bool:
        return self.outputs_state(key, result) == INTACT

    def outputs_state(self, key: str, result: dict, full: bool = False, run: str | None = None) -> str:
        """INTACT, MISSING (a file gone or of another size, or spec.json gone) or CHANGED (not the sha256 recorded).
        Hashes only files whose stat changed since they were last hashed, or every file if `full`, but for
        a `run` that hashed them all in full already (its stat check stands for it: see the module)."""
        folder, verified_path = self.artifacts(key), self.job_dir(key) / VERIFIED
        spec = self.spec(key)
        if not isinstance(spec, dict) or spec.get("key", key) != key:   # what the entry is of: part of it
            return MISSING
        verified = read_json(verified_path)
        verified = verified if isinstance(verified, dict) else {}
        full = full and not (run is not None and verified.get(RUN_MARK) == run)
        rehashed = False
        if verified.get(CHANGED_MARK):   # known changed: hashed again only once its stat moved (put back as it was?)
            restored = self._changed_file_restored(folder, result, verified)
            if not restored:
                if restored is False:   # hashed again, still not the one recorded: remember that stat
                    _try_write(verified_path, verified)
                return CHANGED
            verified = {name: mark for name, mark in verified.items() if not name.startswith(CHANGED_MARK)}
            rehashed = True
        for name, entry in result.get("manifest", {}).items():
            size, digest = (entry, None) if isinstance(entry, int) else (entry.get("size"), entry.get("sha256"))
            try:
                stat = (folder / name).stat()
            except OSError:
                return MISSING
            if stat.st_size != size:
                return MISSING
            if digest is None or (not full and _unchanged(verified.get(name), stat)):
                continue
            if file_sha256(folder / name) != digest:
                _try_write(verified_path, {**verified, CHANGED_MARK: name})
                return CHANGED
            verified[name], rehashed = _signature(stat), True
        if full and run is not None:
            verified[RUN_MARK], rehashed = run, True
        if rehashed:
            _try_write(verified_path, verified)
        return INTACT

    @staticmethod
    def _changed_file_restored(folder: Path, result: dict, verified: dict) -> bool | None:
        """Whether the file last found changed holds its recorded content again: None when its stat is
        the one it had when last hashed (not read again), else what hashing it finds."""
        name = verified[CHANGED_MARK]
        entry = result.get("manifest", {}).get(name)
        digest = entry.get("sha256") if isinstance(entry, dict) else None
        try:
            stat = (folder / name).stat()
        except OSError:
            return None
        if digest is None or _unchanged(verified.get(f"{CHANGED_MARK}:{name}"), stat):
            return None
        verified[f"{CHANGED_MARK}:{name}"] = _signature(stat)
        return file_sha256(folder / name) == digest

    def keys(self) -> Iterator[str]:
        """The keys of the stored jobs: folders named by a key, in their key's shard (anything else
        under jobs/, a file or folder put there by hand, is not a job)."""
        jobs = self.root / "jobs"
        if jobs.is_dir():
            for shard in sorted(p for p in jobs.iterdir() if p.is_dir() and _SHARD.fullmatch(p.name)):
                for folder in sorted(shard.iterdir()):
                    if folder.name.startswith(shard.name) and _KEY.fullmatch(folder.name) and folder.is_dir():
                        yield folder.name

    def find(self, prefix: str) -> str:
        """The one stored key starting with `prefix` (as git does for commits): hex digits only, so a
        prefix is never a path or a glob pattern."""
        if not re.fullmatch(r"[0-9a-fA-F]*", prefix) or len(prefix) > 64:
            raise StoreError(f"{prefix[:80]!r} is not a job key: give the key's first hex digits (0-9, a-f), "
                             "as `plan RECIPE` lists them")
        prefix = prefix.lower()
        if len(prefix) < 4:
            raise StoreError(f"key prefix {prefix!r} is too short; give at least 4 characters")
        shard = self.root / "jobs" / prefix[:2]
        matches = sorted(p.name for p in shard.glob(f"{prefix}*")) if shard.is_dir() else []
        matches += [p.stem for p in (self.root / "failed").glob(f"{prefix}*.json")] if not matches else []
        if not matches:
            raise StoreError(f"no job {prefix!r} in the store {self.root} "
                             "(`plan RECIPE` lists the keys of a recipe's jobs)")
        if len(set(matches)) > 1:
            raise StoreError(f"key prefix {prefix!r} is ambiguous: {', '.join(m[:12] for m in matches[:5])}")
        return matches[0]

    # --- writing ------------------------------------------------------------------------------
    def new_workdir(self, key: str) -> Path:
        """A private folder for a job in flight (artifacts/ inside), later committed by rename."""
        tmp = self.root / "tmp"
        tmp.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f"{key[:16]}-{os.getpid()}-", dir=tmp))
        (work / ARTIFACTS).mkdir()
        return work

    def commit(self, key: str, workdir: Path, spec: dict, result: dict, measured: Collection[str] = (),
               run: str | None = None) -> None:
        """Write spec and result into `workdir`, then move it into place in one rename; `measured`: the
        value's keys that say how the run went, not what it made (outside its outputs token); `run`: the
        run that makes it (its files, hashed here, are not hashed in full again within that run).

        Call with the job's lock held: an existing (corrupt or stale) entry is replaced."""
        result = dict(result, manifest=_manifest(workdir / ARTIFACTS))
        result["outputs"] = outputs_hash(result, measured)
        write_json_atomic(workdir / VERIFIED, _signatures(workdir / ARTIFACTS) | ({RUN_MARK: run} if run else {}))
        write_json_atomic(workdir / SPEC, spec)
        write_json_atomic(workdir / RESULT, result)
        final = self.job_dir(key)
        final.parent.mkdir(parents=True, exist_ok=True)
        if final.exists():
            shutil.rmtree(self._trash(final), ignore_errors=True)
        os.replace(workdir, final)
        self.failed_path(key).unlink(missing_ok=True)

    def record_failure(self, key: str, failure: dict) -> None:
        write_json_atomic(self.failed_path(key), failure)

    def failure(self, key: str) -> dict | None:
        return read_json(self.failed_path(key))

    def forget_failure(self, key: str) -> None:
        """The job's stored result stands again (kept by a later run): its last failure is history."""
        self.failed_path(key).unlink(missing_ok=True)

    def remove(self, key: str) -> None:
        final = self.job_dir(key)
        if final.exists():
            shutil.rmtree(self._trash(final), ignore_errors=True)
        self.failed_path(key).unlink(missing_ok=True)

    def _trash(self, folder: Path) -> Path:
        """Move a folder out of the way first, so readers never see it half deleted."""
        trash = self.root / "tmp" / f"trash-{folder.name[:16]}-{os.getpid()}-{time.monotonic_ns()}"
        trash.parent.mkdir(parents=True, exist_ok=True)
        os.replace(folder, trash)
        return trash

    # --- locks --------------------------------------------------------------------------------
    @contextmanager
    def lock(self, key: str, wait: bool = False) -> Iterator[bool]:
        """Hold the job's lock; yields False (without holding it) when another process has it."""
        with self._flock(f"{key}.lock", fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB)) as held:
            yield held

    def is_locked(self, key: str) -> bool:
        with self.lock(key) as held:
            return not held

    @contextmanager
    def running(self) -> Iterator[None]:
        """Held by a run while it runs (shared: runs go on side by side), so that gc, which needs the
        store to itself (`collecting`), never removes what a run has just finished and still reads."""
        with self._flock(RUNS_LOCK, fcntl.LOCK_SH):
            yield

    @contextmanager
    def collecting(self) -> Iterator[bool]:
        """The store to itself, for gc; yields False (without it) while a run is running on it."""
        with self._flock(RUNS_LOCK, fcntl.LOCK_EX | fcntl.LOCK_NB) as held:
            yield held

    @contextmanager
    def _flock(self, name: str, mode: int) -> Iterator[bool]:
        """Hold locks/`name` in `mode`; yields False (without it) when a non-blocking mode finds it taken."""
        locks = self.root / "locks"
        locks.mkdir(parents=True, exist_ok=True)
        with open(locks / name, "a") as handle:
            try:
                fcntl.flock(handle, mode)
            except OSError as error:
                if error.errno in (errno.EAGAIN, errno.EACCES):
                    yield False
                    return
                raise
            try:
                yield True
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)


def _manifest(folder: Path) -> dict[str, dict]:
    return {p.relative_to(folder).as_posix(): {"size": p.stat().st_size, "sha256": file_sha256(p)}
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _signatures(folder: Path) -> dict[str, list[int]]:
    return {p.relative_to(folder).as_posix(): _signature(p.stat())
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _signature(stat: os.stat_result) -> list[int]:
    """What tells a file apart from the one last hashed without reading it (DVC's state db keeps the
    first three): the change time too, which no one can set (an outside test rewrote an artifact in
    place and put its mtime back with `touch -r`: `plan` found it intact)."""
    return [stat.st_size, stat.st_mtime_ns, stat.st_ino, stat.st_ctime_ns]


def _unchanged(recorded: Any, stat: os.stat_result) -> bool:
    """Whether `recorded` (a signature in verified.json) is this stat's: one written before the change
    time was kept (three numbers) is compared on those, so an older store is not hashed again in full."""
    now = _signature(stat)
    return isinstance(recorded, list) and len(recorded) in (3, len(now)) and recorded == now[:len(recorded)]


def file_sha256(path: Path) -> str:
    with open(path, "rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def _try_write(path: Path, value: Any) -> None:
    try:
        write_json_atomic(path, value)
    except OSError:
        pass  # a read-only store: the check is only repeated next time
