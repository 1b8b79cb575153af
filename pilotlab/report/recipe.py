"""A recipe's report from the job store: one row per evaluated cell, whatever state it is in.

Cells without a result show as failed with the reason (their own failure or a failed dependency)
or as not run yet, never as zeros.
The report is rewritten only when something it shows changed (a stamp over the recipe text, every
shown job's key and stored result, and the report code), so a warm rerun stays quick.
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import platform
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any

from matrix.engine import slug
from matrix.fingerprint import code_fingerprint
from matrix.recipe import Recipe
from matrix.store import Store, read_json, result_token
from pilotlab.errors import PilotlabError
from pilotlab.hardware import host_fingerprint
from pilotlab.report.data import (Claim, Host, ReportData, package_versions, pick_cpu_time, pick_metrics,
                                  pick_spread, pick_unstable)
from pilotlab.report.studies import compare

STAMP = ".stamp"
NOT_RUN = "not run yet"


def report_folder(recipe: Recipe) -> Path:
    return Path(recipe.config.report.folder).expanduser() / slug(recipe.name)


def write_recipe_report(recipe: Recipe, store: Store, jobs: list, force: bool = True) -> Path | None:
    """Write the report of `jobs` (the recipe's plan) from the store; unless `force`, only when
    something it shows changed. Returns the folder, or None when it was left as it was.

    The report is written into a new folder beside the old one, then swapped in: a reader (or a
    second run writing the same report) never sees half a report. Writers of one folder take turns."""
    folder = report_folder(recipe)
    _check_replaceable(folder, recipe)
    stamp = _stamp(recipe, jobs, store)
    if not force and _shown(folder) == stamp:
        return None
    from pilotlab.report.writer import write_report  # matplotlib: only when the report is rewritten
    with _writing(folder) as staging:
        if not force and _shown(folder) == stamp:
            return None                   # another run wrote this very report while we waited
        write_report(build_report_data(recipe, jobs, store), staging)
        (staging / STAMP).write_text(json.dumps({**stamp, "files": _files(staging)}))
        _swap(staging, folder, recipe)
    return folder


def _shown(folder: Path) -> dict | None:
    """What the report in `folder` shows (its stamp without the list of the files it wrote)."""
    stamp = read_json(folder / STAMP)
    return {k: v for k, v in stamp.items() if k != "files"} if isinstance(stamp, dict) else None


def _files(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if not p.is_dir())


def _keep_users_files(old: Path, staging: Path) -> None:
    """Files the old report did not write (a user's notes put in the folder) move into the new one."""
    stamp = read_json(old / STAMP)
    written = stamp.get("files") if isinstance(stamp, dict) else None
    if not isinstance(written, list):   # a report from before the list was kept: all of it was the report's
        return
    for name in sorted(set(_files(old)) - set(written) - {STAMP}):
        target = staging / name
        if not target.exists():   # a name the new report writes is the report's
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(old / name, target)


@contextmanager
def _writing(folder: Path) -> Iterator[Path]:
    """Hold `folder`'s writer lock and yield an empty staging folder beside it (removed after)."""
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        lock = open(folder.parent / f".{folder.name}.lock", "a")
        staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.new-", dir=folder.parent))
    except OSError as error:
        raise PilotlabError(f"report.folder: cannot write the report to {folder} ({error.strerror or error}); "
                            "set report.folder in the recipe to a folder you can write") from None
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield staging
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        lock.close()


def _check_replaceable(folder: Path, recipe: Recipe) -> None:
    """A report replaces only this recipe's report (a folder holding our stamp, naming the recipe) or an
    empty folder: never a file or a folder of the user's that happens to sit where the recipe's name and
    report.folder point, nor the report of another recipe whose name makes the same folder name."""
    name = recipe.name
    if not (folder.exists() or folder.is_symlink()):
        return
    if folder.is_dir() and not folder.is_symlink() and (folder / STAMP).is_file():
        other = _stamped_recipe(folder, name)
        if other == name:
            return
        raise recipe.error(f"{folder} holds the report of recipe {other!r}, and recipe {name!r} makes the same "
                           "folder name; give one of them another name or report.folder", ["report", "folder"])
    if folder.is_dir() and not folder.is_symlink() and not any(folder.iterdir()):
        return
    what = "a folder that is not a pilotlab report (it has no .stamp)" if folder.is_dir() else "not a folder"
    raise recipe.error(f"{folder} is {what}, and writing the report would replace it; move it away, or give the "
                       "recipe another name or report.folder", ["report", "folder"])


def _stamped_recipe(folder: Path, name: str) -> str:
    """The name of the recipe whose report `folder` holds (a stamp from before names were kept in it
    is taken for this recipe's: it is a pilotlab report all the same)."""
    stamp = read_json(folder / STAMP)
    return stamp.get("recipe", name) if isinstance(stamp, dict) else name


def _swap(staging: Path, folder: Path, recipe: Recipe) -> None:
    """Put `staging` where `folder` is: the old report moves aside first, then goes."""
    _check_replaceable(folder, recipe)   # again, under the writers' lock: a folder may have appeared since
    old = folder.parent / f".{folder.name}.old-{os.getpid()}"
    if folder.exists():
        _keep_users_files(folder, staging)
        os.replace(folder, old)
    os.replace(staging, folder)
    os.chmod(folder, 0o755)          # mkdtemp makes it private; a report is for reading
    shutil.rmtree(old, ignore_errors=True)


def build_report_data(recipe: Recipe, jobs: list, store: Store) -> ReportData:
    rows = [_row(job, store) for job in jobs if job.kind in ("offline", "online")]
    host = _host(jobs, store)
    rows = [_timed_here(row, recipe, host) for row in rows]
    histories = {job.name.removeprefix("train "): _history(job, store) for job in jobs if job.kind == "train"}
    data = ReportData.from_dict({
        "recipe_name": recipe.name, "description": recipe.description, "recipe_text": recipe.text,
        "versions": package_versions(), "host": host, "date": datetime.now().isoformat(timespec="seconds"),
        "rows": rows, "histories": {name: h for name, h in histories.items() if h},
        "training_worlds": training_worlds(recipe), "same_as": same_as(recipe),
        **_trainings(recipe, jobs, store),
        "sources": {job.name.removeprefix("train "): text for job in jobs if job.kind == "train"
                    and (text := model_source(store.result(job.key)))}})
    study = recipe.config.report.compare_with
    if study is None:
        return data
    title, checks = compare(data, study)
    return data.model_copy(update={"comparison_title": title,
                                   "comparison": tuple(Claim(**vars(check)) for check in checks)})


def same_as(recipe: Recipe) -> dict[str, list[str]]:
    """Names of the matrix planned as another name with the same definition (matrix.grid): shown name -> others."""
    alike = recipe.grid.alike() if recipe.grid is not None else {}
    return {str(first): [str(name) for name in others] for pairs in alike.values() for first, others in pairs}


def training_worlds(recipe: Recipe) -> dict[str, list[str]]:
    """model -> the BM worlds its training recordings were made in (the world-shift section's reference)."""
    config, found = recipe.config, {}
    for name, model in config.models.items():
        record = getattr(config.datasets.get(model.data), "record", None)
        if record is not None and record.worlds:
            found[name] = list(record.worlds)
    return found


def _row(job, store: Store) -> dict[str, Any]:
    identity = dict(job.labels)
    result = store.result(job.key)
    row = {**identity, "kind": job.kind, "job_keys": {job.kind: job.key}, **_made_by(job)}
    if result is None:
        failure = store.failure(job.key)
        status, reason = ("failed", failure["error"]) if failure else _why_not_run(job, store)
        return {**row, "status": status, "reason": reason}
    row |= row_from_result(result, store.artifacts(job.key))
    if job.kind == "online" and row["status"] == "ok" and (why := _replayed_unstable(job, store)):
        row["unstable"] = {"latency_ms": why}
    if job.kind == "offline" and row["status"] == "ok":
        row = _artifact_figures(job, store) | row
        if trained_on := _trained_on(job):
            row["trained_on"] = trained_on
    return row


def _made_by(job) -> dict[str, Any]:
    """The built-in strategy (and its options) of the optimize job that made the row's network."""
    artifact = job.deps.get("artifact")
    if artifact is None or artifact.kind != "optimize":
        return {}
    return {"runs": artifact.params["strategy"], "options": dict(artifact.params.get("options") or {})}


def _trained_on(job) -> tuple[str, ...]:
    """The offline job's test recordings (frames jobs) that its network was trained on too."""
    test = {dep.key: dep.name.removeprefix("frames ") for dep in job.deps.get("test", ())}
    stack, seen = [job.deps.get("artifact")], set()
    while stack:
        dep = stack.pop()
        if dep is None or dep.key in seen:
            continue
        seen.add(dep.key)
        if dep.kind == "train":
            return tuple(sorted(test[frames.key] for frames in dep.deps.get("frames", ()) if frames.key in test))
        stack.extend(dep.dep_jobs())
    return ()


ARTIFACT_FIGURES = ("params", "nonzero_params", "sparsity")


def _artifact_figures(job, store: Store) -> dict[str, Any]:
    """The parameter counts and sparsity of the network an offline row evaluates: its optimize job's figures
    (the offline job measures MSE and takes its timings; the columns stayed empty in every report)."""
    artifact = job.deps.get("artifact")
    value = ((store.result(artifact.key) if artifact is not None else None) or {}).get("value") or {}
    return {name: value[name] for name in ARTIFACT_FIGURES if value.get(name) is not None}


def _timed_here(row: dict[str, Any], recipe: Recipe, host: Host) -> dict[str, Any]:
    """An offline row of a profile whose latencies come from a device's file was timed on this host, not
    on that device: its timings are marked (no "fastest on DEVICE" is drawn from them), with the reason."""
    options = recipe.config.hardware.get(row.get("hardware"))
    if row.get("kind") != "offline" or row.get("status") != "ok" or getattr(options, "latency_file", None) is None:
        return row
    why = (f"timed on this report's host ({host.cpu}, {host.cores} cores), not on "
           f"{row['hardware']}; {row['hardware']}'s laps replay its latency file ({Path(options.latency_file).name})")
    return {**row, "unstable": {name: why for name in ("latency_ms", "throughput_ips")}}


def _replayed_unstable(job, store: Store) -> str | None:
    """Why the timing a lap replays stayed disturbed (None: it did not, or nothing was replayed):
    the lap's brain frequency and outcome rest on it, so the lap is marked as its timing is."""
    timing = job.deps.get("timing")
    result = store.result(timing.key) if timing is not None else None
    reason = pick_unstable((result or {}).get("value") or {}).get("latency_ms")
    if reason is None:
        return None
    return f"it replays the timing of {timing.name}, which stayed disturbed ({reason})"


def row_from_result(result: dict[str, Any], artifacts: Path) -> dict[str, Any]:
    """The report fields of a finished job: status (and reason), its metrics, their spread over
    repeated laps (online jobs), the timings that stayed disturbed (offline jobs), and the
    trajectory picture, a path under the job's `artifacts`."""
    if result["status"] != "ok":
        return {"status": result["status"], "reason": result.get("reason") or "?"}
    value = result.get("value", {})
    row = {"status": "ok", **pick_metrics(value)}
    if spread := pick_spread(value):
        row["spread"] = spread
    if unstable := pick_unstable(value):
        row["unstable"] = unstable
    if cpu_time := pick_cpu_time(value):
        row["cpu_time"] = cpu_time
    if value.get("trajectory"):
        row["trajectory"] = str(artifacts / value["trajectory"])
    if value.get("latency_source"):
        row["latency_source"] = value["latency_source"]
    if value.get("tolerance_laps"):
        row |= {"tolerance": value["tolerance_laps"], "tolerance_at_least": bool(value.get("tolerance_at_least"))}
    return row


def _why_not_run(job, store: Store) -> tuple[str, str]:
    """(status, reason) of a job that has no result: failed, "dependency failed: <name>: <error>", when a
    job upstream failed; not applicable, with its reason, when one upstream is (so will this job be: the
    report said "not run yet" of a cell a run stopped before, whose optimize job was not applicable);
    else not run, "not run yet"."""
    stack, seen = list(job.dep_jobs()), set()
    while stack:
        dep = stack.pop()
        if dep.key in seen:
            continue
        seen.add(dep.key)
        result = store.result(dep.key)
        if result is not None and result.get("status") == "not_applicable":
            return "not_applicable", result.get("reason") or "?"
        failure = store.failure(dep.key) if result is None else None
        if failure is not None:
            return "failed", f"dependency failed: {dep.name}: {failure.get('error', '?')}"
        stack.extend(dep.dep_jobs())
    return "not_run", NOT_RUN


def _trainings(recipe: Recipe, jobs: list, store: Store) -> dict[str, dict]:
    """The report's training_data (what each model trained on) and training_warnings (too little data)."""
    data, warnings = {}, {}
    for job in (job for job in jobs if job.kind == "train"):
        model, result = job.name.removeprefix("train "), store.result(job.key)
        if text := training_data(recipe, model, result):
            data[model] = text
        if said := ((result or {}).get("value") or {}).get("warnings"):
            warnings[model] = said
    return {"training_data": data, "training_warnings": warnings}


def training_data(recipe: Recipe, model: str, result: dict | None) -> str | None:
    """What a model was trained on, for people: "trained on dataset 'train': 4 recording(s), 7,609 frames (1,903
    more held out for validation, by recording)"; None where it was not trained here or has not run."""
    value = (result or {}).get("value") or {}
    spec = recipe.config.models.get(model)
    if not value.get("trained") or spec is None:
        return None
    held = (f" ({value.get('val_frames', 0):,} more held out for validation, by {value.get('val_by')})"
            if value.get("val_frames") else " (none held out for validation)")
    return (f"trained on dataset {spec.data!r}: {value.get('recordings', '?')} recording(s), "
            f"{value.get('train_frames', 0):,} frames{held}")


def model_source(result: dict | None) -> str | None:
    """Where a model the user brought came from, for people: "network nets/x.py:Net (sha256 1a2b3c4d5e6f),
    weights w.pth (sha256 ...)"; None for a built-in arch or a train job that has not run."""
    source = ((result or {}).get("value") or {}).get("source") or {}
    if source.get("kind") in (None, "arch") and "weights" not in source:
        return None
    parts = [f"{source['kind']} {source.get('file') or source.get('arch')}"
             + (f" (sha256 {source['sha256'][:12]})" if source.get("sha256") else "")]
    if source.get("weights"):
        parts.append(f"weights {source['weights']} (sha256 {source.get('weights_sha256', '')[:12]})")
    trained = ((result or {}).get("value") or {}).get("trained")
    return ", ".join(parts) + ("" if trained is None else ", trained here" if trained else ", used as it is")


def _history(job, store: Store) -> list[dict]:
    history = read_json(store.artifacts(job.key) / "history.json")
    return history if isinstance(history, list) else []


def _host(jobs: list, store: Store) -> Host:
    """The host the timings were measured on (from the timing jobs), else this machine; and the host that
    timed each profile standing for another machine (worker_resource). A timing job's host record (its
    fingerprint, in its key) has no OS: it is this machine's when the record is."""
    found, elsewhere = None, {}
    for job in (job for job in jobs if job.kind == "timing"):
        value = (store.result(job.key) or {}).get("value", {})
        host, profile = value.get("host"), value.get("hardware") or {}
        if host and profile.get("worker_resource"):
            cores = f", {host['cores']} cores" if host.get("cores") else ""
            elsewhere[profile["name"]] = f"{value.get('hostname', '?')} ({host.get('cpu') or 'unknown CPU'}{cores})"
        elif host and found is None:
            here = platform.platform(terse=True) if host == host_fingerprint() else ""
            found = Host(cpu=host.get("cpu") or "unknown CPU", cores=host.get("cores"), gpu=host.get("gpu"), os=here)
    return (found or Host.detect()).model_copy(update={"elsewhere": elsewhere})


def _stamp(recipe: Recipe, jobs: list, store: Store) -> dict:
    """What the report shows (its recipe's name, and a digest of the recipe text, the report code and
    every result it shows): the report is rewritten only when this changes."""
    digest = hashlib.sha256(recipe.text.encode())
    digest.update(code_fingerprint(["pilotlab.report"]).encode())
    for job in jobs:
        result = store.result(job.key) if job.kind in ("offline", "online", "train") else None
        digest.update(f"{job.key}:{result_token(result) if result else 'missing'}\n".encode())   # a rerun is new
    return {"recipe": recipe.name, "digest": digest.hexdigest()}
