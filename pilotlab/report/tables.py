"""The report's tables, of the 2022 study's shape, as plain view models that both templates render.

Offline: Method | Model size | MSE | Inference time | Throughput | Size × | Speed-up × | MSE Δ, one
table per hardware and test set. Simulation: Method | Lap | Average speed | Position deviation MAE |
Brain iteration frequency | Mean inference time | Real-time factor, one table per hardware and circuit.
Ratios are taken against the baseline strategy of the same model in the same table. Where a lap
was repeated from several start points, a cell shows the mean ± the sample standard deviation over
the runs (`8.95 ± 0.12`) and the lap cell how many laps were completed (`✓ 3/3, 47.8 ± 0.4 s`,
`✗ 2/3, 87 %`); a single run shows its value alone, as before. Inference time and throughput show
their 10th–90th percentiles in brackets; a timing that stayed disturbed is marked ⚠ (as is a speed-up
drawn from one, or from two timings taken with the machine in another state), with the reason in a
note under the table, and each offline table says in one line how its timings were taken.
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from pilotlab.columns import BY_NAME
from pilotlab.report.data import ReportData, ReportRow, timing_issue

MISSING = "—"
UNSTABLE = "⚠"
CPU_TIME = "CPU"   # after a timing that is the calls' thread CPU time (the wall clock was disturbed)
PERCENTILES = {"latency_ms": ("latency_p10_ms", "latency_p90_ms"),
               "throughput_ips": ("throughput_p10_ips", "throughput_p90_ips")}
COUNT_COLUMNS = {"params", "nonzero_params", "throughput_batch", "threads", "test_frames", "off_road_events",
                 "latency_runs", "timing_blocks", "timing_calls_discarded"}


@dataclass(frozen=True)
class Cell:
    text: str
    sort: float | None = None       # numeric sort key; None sorts last (missing / not applicable)
    title: str = ""                 # tooltip in the HTML page
    missing: bool = False


@dataclass(frozen=True)
class TableRow:
    method: str
    source: ReportRow
    cells: tuple[Cell, ...]
    note: str = ""                  # "not applicable: reason" / "failed: reason" spans the metric cells


@dataclass(frozen=True)
class Table:
    title: str
    kind: str
    hardware: str
    place: str
    headers: tuple[str, ...]        # after the Method column
    rows: tuple[TableRow, ...]
    notes: tuple[str, ...] = field(default=())
    method: str = ""                # how the figures were measured, one line


def format_value(name: str, value: object) -> str:
    """A metric value as a person reads it: 3 significant digits, no exponent where avoidable."""
    if value is None:
        return MISSING
    if isinstance(value, bool):
        return "yes" if value else "no"
    if name in COUNT_COLUMNS or name == "throughput_ips":
        return f"{value:,.0f}"
    if name == "percentage_completed":
        return f"{value:.0f} %"
    return significant(float(value))


def significant(value: float, digits: int = 3) -> str:
    if value == 0 or not math.isfinite(value):
        return f"{value:g}"
    magnitude = math.floor(math.log10(abs(value)))
    if magnitude >= digits - 1:
        return f"{value:,.0f}"
    if magnitude < -5:
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits - 1 - magnitude}f}"


def plus_minus(text: str, std: float) -> str:
    """`text ± std`, the std given to the decimals of `text` (the mean as shown), or to one
    significant digit where those would round it to zero."""
    decimals = len(text.rpartition(".")[2]) if "." in text and "e" not in text else 0
    shown = f"{std:,.{decimals}f}"
    if std > 0 and float(shown.replace(",", "")) == 0:
        shown = significant(std, 1)
    return f"{text} ± {shown}"


def method_label(row: ReportRow, data: ReportData) -> str:
    return row.strategy if len(data.models()) <= 1 else f"{row.model} · {row.strategy}"


def metric_cell(row: ReportRow, name: str) -> Cell:
    value = row.get(name)
    column = BY_NAME[name]
    title = f"{name}: {column.doc}" + (f" ({column.unit})" if column.unit else "")
    if value is None:
        return Cell(MISSING, None, f"{title}: not measured", missing=True)
    text, spread = format_value(name, value), row.spread_of(name)
    if spread is None or spread.std is None or isinstance(value, bool):
        return Cell(text, float(value), title)
    extent = f", min {format_value(name, spread.min)}, max {format_value(name, spread.max)}"
    return Cell(plus_minus(text, spread.std), float(value),
                f"{title}: mean ± standard deviation of {spread.runs} runs{extent}")


def timed_cell(row: ReportRow, name: str) -> Cell:
    """A timing: `2.31 (2.25–2.60)` with its 10th–90th percentiles, and ⚠ where it stayed disturbed."""
    cell = metric_cell(row, name)
    if cell.missing:
        return cell
    text, title = cell.text, cell.title
    low, high = (row.get(p) for p in PERCENTILES[name])
    if low is not None and high is not None:
        text += f" ({format_value(name, low)}–{format_value(name, high)})"
        title += "; 10th–90th percentile in brackets"
    if reason := row.unstable_reason(name):
        text, title = f"{text} {UNSTABLE}", f"{title}; UNSTABLE: {reason}"
    elif reason := row.cpu_time_reason(name):
        text, title = f"{text} {CPU_TIME}", f"{title}; CPU time: {reason}"
    return Cell(text, cell.sort, title)


def speedup_cell(row: ReportRow, baseline: ReportRow | None) -> Cell:
    cell = ratio_cell(row.get("latency_ms"), baseline.get("latency_ms") if baseline else None, "faster")
    issue = None if cell.missing else timing_issue([baseline, row])
    if issue is None:
        return cell
    return Cell(f"{cell.text} {UNSTABLE}", cell.sort, f"{cell.title}; not to be trusted: {issue}")


def lap_cell(row: ReportRow) -> Cell:
    done, seconds, share = row.get("lap_completed"), row.get("lap_seconds"), row.get("percentage_completed")
    if done is None:
        return Cell(MISSING, None, "lap not measured", missing=True)
    laps = row.spread_of("lap_completed")
    if laps is not None and laps.completed is not None:
        return repeated_lap_cell(row, laps.completed, laps.runs)
    if done:
        text = f"✓ {format_value('lap_seconds', seconds)} s" if seconds is not None else "✓ completed"
        return Cell(text, float(seconds) if seconds is not None else 0.0, "lap completed (simulated seconds)")
    text = f"✗ {format_value('percentage_completed', share)}" if share is not None else "✗ lost"
    return Cell(text, 1e9 - float(share or 0), "lap not completed (share of the circuit driven)")


def repeated_lap_cell(row: ReportRow, completed: int, runs: int) -> Cell:
    """The lap cell of a lap repeated `runs` times: `✓ 3/3, 47.8 ± 0.4 s` or `✗ 2/3, 87 %`."""
    seconds, share = row.get("lap_seconds"), row.get("percentage_completed")
    if completed == runs:
        timing = "" if seconds is None else ", " + metric_cell(row, "lap_seconds").text + " s"
        return Cell(f"✓ {completed}/{runs}{timing}", float(seconds) if seconds is not None else 0.0,
                    f"{completed} of {runs} laps completed (mean ± std of their simulated seconds)")
    driven = "" if share is None else ", " + format_value("percentage_completed", share)
    return Cell(f"✗ {completed}/{runs}{driven}", 1e9 - 1000 * completed - float(share or 0),
                f"{completed} of {runs} laps completed (mean share of the circuit driven)")


def ratio_cell(value: float | None, baseline: float | None, how: str) -> Cell:
    """`how`: "smaller" (baseline/value, e.g. size), "faster" (baseline/value), "delta" (value - baseline)."""
    if value is None or baseline is None:
        reason = "no baseline to compare with" if baseline is None else "not measured"
        return Cell(MISSING, None, reason, missing=True)
    if how == "delta":
        delta = float(value) - float(baseline)
        return Cell(("+" if delta > 0 else "−" if delta < 0 else "±") + significant(abs(delta), 2),
                    delta, "difference from the baseline (negative is better)")
    if not value:
        return Cell(MISSING, None, "zero value: no ratio", missing=True)
    ratio = float(baseline) / float(value)
    return Cell(f"{ratio:.2f}×", ratio, f"baseline / this ({how} above 1×)")


OFFLINE_COLUMNS = (("Model size (MB)", "size_mb"), ("Compressed (MB, gzip)", "size_gz_mb"), ("MSE", "mse"), ("Inference time (ms)", "latency_ms"),
                   ("Throughput (images/s)", "throughput_ips"))
ONLINE_COLUMNS = (("Average speed (m/s)", "average_speed"), ("Position deviation MAE (m)", "position_deviation_mae_m"),
                  ("Brain iteration frequency (Hz)", "brain_frequency_sim_hz"),
                  ("Mean inference time (ms)", "mean_inference_ms"), ("Real-time factor", "real_time_factor"))
OFFLINE_HEADERS = tuple(h for h, _ in OFFLINE_COLUMNS) + ("Size ×", "Speed-up ×", "MSE Δ")
ONLINE_HEADERS = ("Lap",) + tuple(h for h, _ in ONLINE_COLUMNS)


def offline_cells(row: ReportRow, baseline: ReportRow | None) -> tuple[Cell, ...]:
    base = baseline.get if baseline else (lambda _name: None)
    return tuple(timed_cell(row, name) if name in PERCENTILES else metric_cell(row, name)
                 for _, name in OFFLINE_COLUMNS) + (
        ratio_cell(row.get("size_mb"), base("size_mb"), "smaller"),
        speedup_cell(row, baseline),
        ratio_cell(row.get("mse"), base("mse"), "delta"),
    )


def online_cells(row: ReportRow, _baseline: ReportRow | None) -> tuple[Cell, ...]:
    """A lap's cells; where the timing it replays stayed disturbed, ⚠ on its lap and inference time."""
    cells = (lap_cell(row),) + tuple(metric_cell(row, name) for _, name in ONLINE_COLUMNS)
    if not (reason := row.unstable_reason("latency_ms")):
        return cells
    return tuple(Cell(f"{c.text} {UNSTABLE}", c.sort, f"{c.title}; UNSTABLE: {reason}")
                 if header in ("Lap", "Mean inference time (ms)") and not c.missing else c
                 for header, c in zip(ONLINE_HEADERS, cells))


TOLERANCE_HEADER = "Latency tolerance (ms)"
# BehaviorMetrics' own figures (pilotlab/columns.py BEHAVIORMETRICS), shown where the laps have them
BM_ONLINE_COLUMNS = (("BM deviation MAE (1000^d)", "bm_position_deviation_mae"),
                     ("BM completed (%)", "bm_percentage_completed"))


def tolerance_cell(row: ReportRow) -> Cell:
    """The largest injected latency at which the lap is still completed: `140`, `≥ 1000` (never lost
    in the searched range) or `lost at 0` (lost with nothing injected)."""
    value, title = row.get("latency_tolerance_ms"), "latency_tolerance_ms: " + BY_NAME["latency_tolerance_ms"].doc
    if value is None:
        lost = row.status == "ok" and row.tolerance and not row.tolerance[0].lap_completed
        return Cell("lost at 0", -1.0, title) if lost else Cell(MISSING, None, title + ": not searched", missing=True)
    return Cell(("≥ " if row.tolerance_at_least else "") + f"{value:.0f}", float(value), title)


def online_layout(data: ReportData) -> tuple[tuple[str, ...], Callable]:
    """The simulation tables' headers and cells: ours, then BehaviorMetrics' figures and the latency
    tolerance where some lap has them."""
    rows = data.of_kind("online")
    bm = [(header, name) for header, name in BM_ONLINE_COLUMNS if any(row.get(name) is not None for row in rows)]
    tolerance = any(row.tolerance for row in rows)

    def cells(row: ReportRow, baseline: ReportRow | None) -> tuple[Cell, ...]:
        extra = tuple(metric_cell(row, name) for _, name in bm) + ((tolerance_cell(row),) if tolerance else ())
        return online_cells(row, baseline) + extra
    return ONLINE_HEADERS + tuple(header for header, _ in bm) + ((TOLERANCE_HEADER,) if tolerance else ()), cells


def build_tables(data: ReportData, kind: str) -> list[Table]:
    """One table per (hardware, test set) offline or (hardware, circuit and direction) online; the
    simulation tables get BehaviorMetrics' figures and a latency tolerance column where laps have them."""
    headers, cells_of = (OFFLINE_HEADERS, offline_cells) if kind == "offline" else online_layout(data)
    groups: dict[tuple[str, str], list[ReportRow]] = {}
    for row in data.of_kind(kind):
        groups.setdefault((row.hardware, row.place), []).append(row)
    tables = [_table(data, kind, hardware, place, rows, headers, cells_of)
              for (hardware, place), rows in groups.items()]
    return [_with_reference_note(table, groups) for table in tables] if kind == "online" else tables


def _with_reference_note(table: Table, groups: dict[tuple[str, str], list[ReportRow]]) -> Table:
    """A table without the reference brains' laps, where another profile's table of the place has them
    (replayed, they are driven on one CPU profile: pilotlab.planning.laps.reference_cells), says where."""
    if any(row.model == REFERENCE for row in groups[table.hardware, table.place]):
        return table
    where = [hardware for (hardware, place), rows in groups.items()
             if place == table.place and any(row.model == REFERENCE for row in rows)]
    if not where:
        return table
    return replace(table, notes=table.notes + (
        f"The reference brains' laps are in the {where[0]} table: replayed, they do not depend on the CPU profile.",))


REFERENCE = "reference"   # the model label of the reference brains' laps


def _table(data: ReportData, kind: str, hardware: str, place: str, rows: list[ReportRow],
           headers: tuple[str, ...], cells_of: Callable) -> Table:
    order = {s: i for i, s in enumerate(data.strategies())}
    rows = sorted(rows, key=lambda r: (data.models().index(r.model), order[r.strategy]))
    # a lap in a BM world is headed by the world (its circuit field holds the world's name)
    where = "test set" if kind == "offline" else "world" if rows[0].world else "circuit"
    title = f"{hardware} · {where} {place}"
    if _all_alike_and_not_measured(rows):  # e.g. every CUDA cell on a host without a GPU: one line
        methods = ", ".join(method_label(r, data) for r in rows)
        note = f"{rows[0].status.replace('_', ' ')} for all {len(rows)} methods ({methods}): {rows[0].reason}"
        return Table(title, kind, hardware, place, headers, (), (note,))
    baselines = {r.model: r for r in rows if r.strategy == data.baseline and r.status == "ok"}
    notes = tuple(f"No usable {data.baseline!r} row for {model} here: ratios are not shown."
                  for model in _unique(r.model for r in rows) if model not in baselines) if kind == "offline" else \
        _latency_notes(rows, data)
    table_rows = tuple(TableRow(method_label(r, data), r, cells_of(r, baselines.get(r.model)), _note(r)) for r in rows)
    if kind != "offline":
        notes += tuple(f"{UNSTABLE} {method_label(r, data)}: no verdict from this lap: {reason}."
                       for r in rows if (reason := r.unstable_reason("latency_ms")))
        return Table(title, kind, hardware, place, headers, table_rows, notes)
    notes += tuple(_timing_notes(data, rows, baselines)) + _training_data_notes(rows)
    return Table(title, kind, hardware, place, headers, table_rows, notes, timing_method(rows))


def _training_data_notes(rows: list[ReportRow]) -> tuple[str, ...]:
    """Outside test: a test set that is (partly) the training data was evaluated without a word."""
    seen = dict.fromkeys((r.model, r.trained_on) for r in rows if r.trained_on)
    return tuple(f"{UNSTABLE} {model}: the test set holds recordings it was trained on ({', '.join(names)}): its MSE "
                 "here is partly on training data; give the recipe a test set of other recordings" for model, names in seen)


def _timing_notes(data: ReportData, rows: list[ReportRow], baselines: dict[str, ReportRow]) -> list[str]:
    """One note per timing marked ⚠: the figure that stayed disturbed, or the speed-up that cannot be trusted."""
    notes = []
    for row in rows:
        for name, label in (("latency_ms", "inference time"), ("throughput_ips", "throughput")):
            if reason := row.unstable_reason(name):
                notes.append(f"{UNSTABLE} {method_label(row, data)}: {label} unstable: {reason}.")
            elif reason := row.cpu_time_reason(name):
                notes.append(f"{CPU_TIME} {method_label(row, data)}: {label} in CPU time: {reason}.")
        base = baselines.get(row.model)
        if base is not None and base is not row and not row.unstable_reason("latency_ms") \
                and not base.unstable_reason("latency_ms") and (issue := timing_issue([base, row])):
            notes.append(f"{UNSTABLE} {method_label(row, data)}: speed-up not to be trusted: {issue}.")
    return notes


def timing_method(rows: list[ReportRow]) -> str:
    """How the table's timings were taken, in one line: threads, repetitions, statistic, interference."""
    timed = [r for r in rows if r.get("latency_ms") is not None]
    if not timed:
        return ""
    threads = "/".join(str(t) for t in sorted({int(r.get("threads")) for r in timed if r.get("threads")}))
    line = f"Timings on {threads or '?'} thread(s), one method at a time: inference time is the median of " \
           f"{_extent(timed, 'latency_runs')} timed batch-1 calls per method"
    batches = sorted({int(r.get("throughput_batch")) for r in timed if r.get("throughput_batch")})
    if batches:
        line += f", throughput the batch of {'/'.join(map(str, batches))} over the median time of its calls"
    line += ", each with its 10th–90th percentile; calls that a wait of this process's threads for a CPU may " \
            "have overlapped were set aside and re-measured"
    discarded = sum(int(r.get("timing_calls_discarded") or 0) for r in timed)
    others = [r.get("timing_other_cores") for r in timed if r.get("timing_other_cores") is not None]
    if others:
        low, high = f"{min(others):.2f}", f"{max(others):.2f}"
        used = low if low == high else f"{low}–{high}"
        line += f" ({discarded:,} calls; other processes used {used} cores meanwhile)"
    return line + f"; {UNSTABLE} marks a timing that stayed disturbed: no conclusion is drawn from it."


def _extent(rows: list[ReportRow], name: str) -> str:
    values = [int(r.get(name)) for r in rows if r.get(name) is not None]
    if not values:
        return "the"
    low, high = min(values), max(values)
    return f"{low:,}" if low == high else f"{low:,}–{high:,}"


def _latency_notes(rows: list[ReportRow], data: ReportData) -> tuple[str, ...]:
    """Where the laps' latencies came from, when they were replayed (one line per source), and which
    rows replayed host stalls unscaled (a lap's source ends with its own count: one line per count did
    not say whose it was)."""
    replayed = [r for r in rows if r.status == "ok" and r.latency_source and not r.latency_source.startswith("none")]
    sources = _unique(STALLS.sub("", r.latency_source) for r in replayed)
    notes = tuple(f"Latencies replayed from the {source}." for source in sources)
    stalled = [f"{method_label(r, data)} {stalls}" for r in replayed if (stalls := _stalls(r))]
    if stalled:
        from pilotlab.online.latency import STALL_TIMES_MEDIAN   # numpy: only where there is a stall to explain
        notes += (f"Host stalls replayed unscaled (timed calls over {STALL_TIMES_MEDIAN:g}× their median: the host "
                  f"took that time, a slower device would not take it k× longer): {', '.join(stalled)}.",)
    return notes


STALLS = re.compile(r" \((\d+) host stalls? replayed unscaled\)$")


def _stalls(row: ReportRow) -> int:
    found = STALLS.search(row.latency_source or "")
    return int(found.group(1)) if found else 0


def _all_alike_and_not_measured(rows: list[ReportRow]) -> bool:
    return len(rows) > 1 and rows[0].status != "ok" and \
        all((r.status, r.reason) == (rows[0].status, rows[0].reason) for r in rows)


def _note(row: ReportRow) -> str:
    return {"ok": "", "not_applicable": f"not applicable: {row.reason}", "failed": f"failed: {row.reason}",
            "not_run": row.reason}[row.status]


def _unique(values) -> list:
    return list(dict.fromkeys(values))


ALL_COLUMNS = tuple(BY_NAME)


def all_results_cells(row: ReportRow) -> tuple[Cell, ...]:
    """Every metric of pilotlab/columns.py, for the page's full results table."""
    return tuple(metric_cell(row, name) for name in ALL_COLUMNS)
