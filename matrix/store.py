"""The job store: content-addressed folders, atomic writes, per-job locks.

    <root>/jobs/<key[:2]>/<key>/   spec.json, result.json, log.txt, artifacts/
    <root>/failed/<key>.json       the last failure of a job (error, traceback, log tail)
    <root>/locks/<key>.lock        held (flock) by the process running the job
    <root>/tmp/                    jobs in flight; renamed into jobs/ when their result is written
    <root>/recipes/<name>.json     the job names and specs of a recipe's last run (reasons, gc)
    <root>/cache/                  scratch shared by jobs (for example decoded frames)

A job is done exactly when `jobs/<key>/result.json` exists: the folder appears by one rename, so a
killed run loses only the jobs it had in flight, and readers never see half a job.
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from matrix.errors import MatrixError

RESULT, SPEC, LOG, ARTIFACTS = "result.json", "spec.json", "log.txt", "artifacts"


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
        """Every artifact the result lists is there with its size (a cheap check, no hashing)."""
        folder = self.artifacts(key)
        for name, size in result.get("manifest", {}).items():
            try:
                if (folder / name).stat().st_size != size:
                    return False
            except OSError:
                return False
        return True

    def keys(self) -> Iterator[str]:
        jobs = self.root / "jobs"
        if jobs.is_dir():
            for shard in sorted(jobs.iterdir()):
                for folder in sorted(shard.iterdir()):
                    yield folder.name

    def find(self, prefix: str) -> str:
        """The one stored key starting with `prefix` (as git does for commits)."""
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

    def commit(self, key: str, workdir: Path, spec: dict, result: dict) -> None:
        """Write spec and result into `workdir`, then move it into place in one rename.

        Call with the job's lock held: an existing (corrupt or stale) entry is replaced."""
        result = dict(result, manifest=_manifest(workdir / ARTIFACTS))
        write_json_atomic(workdir / SPEC, spec)
        write_json_atomic(workdir / RESULT, result)
        final = self.job_dir(key)
        final.parent.mkdir(parents=True, exist_ok=True)
        if final.exists():
            shutil.rmtree(self._trash(final))
        os.replace(workdir, final)
        self.failed_path(key).unlink(missing_ok=True)

    def record_failure(self, key: str, failure: dict) -> None:
        write_json_atomic(self.failed_path(key), failure)

    def failure(self, key: str) -> dict | None:
        return read_json(self.failed_path(key))

    def remove(self, key: str) -> None:
        final = self.job_dir(key)
        if final.exists():
            shutil.rmtree(self._trash(final))
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
        locks = self.root / "locks"
        locks.mkdir(parents=True, exist_ok=True)
        with open(locks / f"{key}.lock", "a") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
            except OSError as error:
                if error.errno in (errno.EAGAIN, errno.EACCES):
                    yield False
                    return
                raise
            try:
                yield True
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)

    def is_locked(self, key: str) -> bool:
        with self.lock(key) as held:
            return not held


def _manifest(folder: Path) -> dict[str, int]:
    return {p.relative_to(folder).as_posix(): p.stat().st_size
            for p in sorted(folder.rglob("*")) if p.is_file()}
