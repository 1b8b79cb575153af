"""`write_report(data, out_dir)`: results.csv, results.json, README.md, index.html, plots/ and trajectories/.

README.md references plots/ and trajectories/ by relative path (GitHub shows them); index.html embeds
every picture as a data URI, its CSS and script inline, and a Content-Security-Policy that allows
nothing but those (no network, no other script), so the page works offline, alone or in the folder.
"""
from __future__ import annotations

import base64
import csv
import io
import json
import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pilotlab
from pilotlab.columns import BY_NAME
import pilotlab.report.render as render
from pilotlab.report.data import CPU_TIME_COLUMNS, ROW_FIELDS, UNSTABLE_COLUMNS, ReportData, ReportRow
from pilotlab.report.plots import CAPTIONS, save_plots
from pilotlab.report.summary import summarise
from pilotlab.report.tables import TOLERANCE_HEADER, all_results_cells, build_tables, method_label
from pilotlab.report.worlds import shift_summary, world_tables


@dataclass(frozen=True)
class ReportPaths:
    folder: Path
    readme: Path
    html: Path
    csv: Path
    json: Path
    plots: dict[str, tuple[Path, Path]]        # plot name -> (png, svg); only the plots that had data
    trajectories: dict[int, Path]              # index in data.rows -> copied picture


@dataclass(frozen=True)
class Picture:
    """A trajectory picture of one online row, copied into the report folder."""
    row: ReportRow
    method: str
    relative: str                   # path inside the report folder (README links it)
    data_uri: str                   # the same picture for index.html
    caption: str


def write_report(data: ReportData, out_dir: Path) -> ReportPaths:
    """Write the whole report for `data` into `out_dir` (created; plots/ and trajectories/ replaced)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    plots = save_plots(data, _fresh(out_dir / "plots"))
    pictures, missing = copy_trajectories(data, _fresh(out_dir / "trajectories"))
    context = build_context(data, out_dir, plots, pictures, missing)
    paths = ReportPaths(out_dir, out_dir / "README.md", out_dir / "index.html", out_dir / "results.csv",
                        out_dir / "results.json", plots, {i: out_dir / p.relative for i, p in pictures.items()})
    _write_text(paths.csv, results_csv(data, pictures))
    _write_text(paths.json, results_json(data, pictures))
    _write_text(paths.readme, render.markdown("README.md.j2", context))
    _write_text(paths.html, render.html("index.html.j2", context))
    return paths


def build_context(data: ReportData, out_dir: Path, plots: dict[str, tuple[Path, Path]],
                  pictures: dict[int, Picture], missing: list[str]) -> dict[str, Any]:
    counts = {status: sum(r.status == status for r in data.rows)
              for status in ("ok", "not_applicable", "failed", "not_run")}
    return {
        "data": data,
        "writer_version": pilotlab.__version__,
        "description": [" ".join(p.split()) for p in re.split(r"\n\s*\n", data.description.strip()) if p.strip()],
        "counts": counts,
        "baseline_note": "" if data.baseline in data.strategies() else " (not among this report's strategies: no ratios)",
        "offline": build_tables(data, "offline"),
        "online": (online := build_tables(data, "online")),
        "bm_columns": any(header.startswith("BM ") for table in online for header in table.headers),
        "tolerance_column": any(TOLERANCE_HEADER in table.headers for table in online),
        "worlds": world_tables(data),
        "world_summary": shift_summary(data),
        "repeated": any((row.repetitions or 1) > 1 for row in data.of_kind("online")),
        "findings": summarise(data),
        "plots": [_plot_entry(name, png, svg, out_dir) for name, (png, svg) in plots.items()],
        "pictures": list(pictures.values()),
        "picture_groups": _group_pictures(pictures.values()),
        "missing_pictures": missing,
        "all_rows": [(row, method_label(row, data), all_results_cells(row)) for row in data.rows],
        "metric_names": list(BY_NAME),
        "job_roles": job_roles(data),
        "filters": {"model": data.models(), "strategy": data.strategies(), "hardware": data.hardware(),
                    "circuit": data.circuits()},
    }


def copy_trajectories(data: ReportData, folder: Path) -> tuple[dict[int, Picture], list[str]]:
    """Copy each online row's trajectory PNG into `folder`; return them by row index, and the missing ones."""
    pictures, missing, used = {}, [], set()
    for index, row in enumerate(data.rows):
        if row.trajectory is None:
            continue
        if not row.trajectory.is_file():
            missing.append(f"{method_label(row, data)} on {row.hardware}, {row.place}: {row.trajectory}")
            continue
        name = _unique_name(_slug(row), used)
        shutil.copyfile(row.trajectory, folder / name)
        pictures[index] = Picture(row, method_label(row, data), f"{folder.name}/{name}",
                                  data_uri(folder / name), _caption(row))
    return pictures, missing


def result_fields(data: ReportData) -> list[str]:
    """The columns of results.csv (and keys of results.json's rows), in order."""
    return [*ROW_FIELDS, *BY_NAME, *UNSTABLE_COLUMNS, *CPU_TIME_COLUMNS, *data.spread_columns(),
            *(f"job_{role}" for role in job_roles(data)), "trajectory"]


def results_rows(data: ReportData, pictures: dict[int, Picture]) -> list[dict[str, Any]]:
    """The tidy rows: identity, status and reason, every metric of pilotlab/columns.py, why a timed
    metric is unstable (`latency_ms_unstable`, empty when stable), why it is thread CPU time
    (`latency_ms_cpu_time`, empty when wall-clock time), the spread over repeated runs,
    job keys, picture; every row has every column (None where there is nothing)."""
    roles, fields = job_roles(data), result_fields(data)
    rows = []
    for index, row in enumerate(data.rows):
        keys = {f"job_{role}": row.job_keys.get(role) for role in roles}
        picture = pictures[index].relative if index in pictures else None
        values = {**row.flat(), **keys, "trajectory": picture}
        rows.append({field: values.get(field) for field in fields})
    return rows


def results_csv(data: ReportData, pictures: dict[int, Picture]) -> str:
    fields = result_fields(data)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for row in results_rows(data, pictures):
        writer.writerow({k: "" if v is None else v for k, v in row.items()})
    return buffer.getvalue()


def results_json(data: ReportData, pictures: dict[int, Picture]) -> str:
    document = {
        "recipe": data.recipe_name, "description": data.description, "date": data.date.isoformat(),
        "host": data.host.model_dump(), "versions": data.versions, "baseline": data.baseline,
        "columns": {c.name: {"unit": c.unit, "doc": c.doc, "better": c.better} for c in BY_NAME.values()},
        "rows": results_rows(data, pictures),
        "histories": {m: [p.model_dump() for p in points] for m, points in data.histories.items()},
    }
    return json.dumps(document, indent=2, ensure_ascii=False) + "\n"


def job_roles(data: ReportData) -> list[str]:
    return list(dict.fromkeys(role for row in data.rows for role in row.job_keys))


def data_uri(path: Path) -> str:
    kind = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
    mime = kind.get(path.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def _plot_entry(name: str, png: Path, svg: Path, out_dir: Path) -> dict[str, str]:
    return {"name": name, "caption": CAPTIONS[name], "png": png.relative_to(out_dir).as_posix(),
            "svg": svg.relative_to(out_dir).as_posix(), "data_uri": data_uri(png)}


def _group_pictures(pictures) -> list[tuple[str, list[Picture]]]:
    groups: dict[str, list[Picture]] = {}
    for picture in pictures:
        groups.setdefault(f"{picture.row.place} · {picture.row.hardware}", []).append(picture)
    return list(groups.items())


def _caption(row: ReportRow) -> str:
    if row.status != "ok":
        return f"{row.status.replace('_', ' ')}: {row.reason}"
    done, laps = row.get("lap_completed"), row.spread_of("lap_completed")
    if done is None:
        return "lap not measured"
    if laps is not None and laps.completed is not None:
        return f"{laps.completed} of {laps.runs} laps completed"
    if done:
        seconds = row.get("lap_seconds")
        return f"lap completed in {seconds:.1f} s" if seconds is not None else "lap completed"
    share = row.get("percentage_completed")
    return f"lap lost at {share:.0f} %" if share is not None else "lap lost"


def _slug(row: ReportRow) -> str:
    parts = (row.model, row.strategy, row.hardware, row.circuit, row.direction)
    text = "_".join(p for p in parts if p)
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-.")[:120] or "run"


def _unique_name(stem: str, used: set[str]) -> str:
    name, n = f"{stem}.png", 1
    while name in used:
        n += 1
        name = f"{stem}-{n}.png"
    used.add(name)
    return name


def _fresh(folder: Path) -> Path:
    """An empty folder: plots and pictures of an earlier report must not linger."""
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    return folder


def _write_text(path: Path, text: str) -> None:
    """Atomically: a reader never sees a half-written report file."""
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
        stream.write(text)
    os.chmod(temporary, 0o644)
    os.replace(temporary, path)
