"""A short generated summary of the findings: the best strategy per criterion, and who loses the lap.

No line is drawn from a timing that stayed disturbed (or from two taken with the machine in another
state): where one is, the line says so instead of naming a fastest method.

Findings are (label, text) pairs of plain text, the templates escape them; a finding that asks for a
command names it apart (`command`, then `then`), for the templates to show it as code.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from pilotlab.columns import BY_NAME
from pilotlab.report.data import ReportData, ReportRow, timing_issue
from pilotlab.report.tables import UNSTABLE, format_value, method_label

# "keeps its accuracy": an offline MSE at most this multiple of the baseline's (the 2022 study's question
# is speed without driving worse; a 20 % margin stays above the run-to-run spread of fine-tuned MSEs)
MSE_KEPT = 1.2


@dataclass(frozen=True)
class Finding:
    label: str
    text: str
    command: str = ""      # shown as code after the text
    then: str = ""         # plain text after the command


def summarise(data: ReportData) -> list[Finding]:
    offline, online = data.of_kind("offline"), data.of_kind("online")
    findings = [*_smallest(data, offline), *_most_accurate(data, offline), *_fastest(data, offline),
                *_fastest_accurate(data, offline, online), *_closed_loop(data, online), *_not_run(data, "not_applicable", "Not applicable"),
                *_not_run(data, "failed", "Failed"), *_not_run(data, "not_run", "Not run yet")]
    return findings or [Finding("No results", "no cell produced a measurement")]


def best(rows: Iterable[ReportRow], metric: str) -> ReportRow | None:
    """The row with the best measured value of `metric` (lower or higher, as pilotlab/columns.py says)."""
    measured = [r for r in rows if isinstance(r.get(metric), (int, float))]
    if not measured:
        return None
    pick = max if BY_NAME[metric].better == "higher" else min
    return pick(measured, key=lambda r: r.get(metric))


def baseline_of(data: ReportData, row: ReportRow) -> ReportRow | None:
    for other in data.rows:
        if (other.strategy == data.baseline and other.status == "ok" and other.model == row.model
                and other.kind == row.kind and other.hardware == row.hardware and other.place == row.place):
            return other
    return None


def _smallest(data: ReportData, rows: list[ReportRow]) -> list[Finding]:
    row = best(rows, "size_mb")
    if row is None:
        return []
    size = format_value("size_mb", row.get("size_mb"))
    text = f"{method_label(row, data)}{_ties(data, rows, row, 'size_mb')} — {size} MB"
    return [Finding("Smallest model", text + _versus(data, row, "size_mb", "smaller"))]


def _most_accurate(data: ReportData, rows: list[ReportRow]) -> list[Finding]:
    findings = []
    places = list(dict.fromkeys(r.place for r in rows))
    for place in places:
        here = [r for r in rows if r.place == place]
        row = best(here, "mse")
        if row is not None:
            label = "Lowest MSE" + (f" on {place}" if len(places) > 1 else "")
            text = f"{method_label(row, data)}{_ties(data, here, row, 'mse')} — {format_value('mse', row.get('mse'))}"
            findings.append(Finding(label, text + _mse_delta(data, row)))
    return findings


def _fastest(data: ReportData, rows: list[ReportRow]) -> list[Finding]:
    findings = []
    for hardware in dict.fromkeys(r.hardware for r in rows):
        here = [r for r in rows if r.hardware == hardware]
        for metric, label, unit in (("latency_ms", "Fastest", "ms per image"),
                                    ("throughput_ips", "Highest throughput", "images/s")):
            row = best(here, metric)
            if row is None:
                continue
            if issue := timing_issue(here, metric):
                findings.append(Finding(f"{label} on {hardware}", f"not drawn: {issue}; rerun",
                                        _rerun_timing(data), "when the machine is quieter"))
                continue
            text = f"{method_label(row, data)}{_within_spread(data, here, row, metric)} — " \
                f"{format_value(metric, row.get(metric))} {unit}{_clock(row, metric)}"
            versus = _versus(data, row, metric, "faster") if metric == "latency_ms" else ""
            findings.append(Finding(f"{label} on {hardware}", text + versus))
    return findings


def _rerun_timing(data: ReportData) -> str:
    """The command that measures the timings again (the report knows its recipe by name, not its path)."""
    return f"pilotlab run {data.recipe_name}.yaml --force timing"


def _clock(row: ReportRow, metric: str) -> str:
    """" (CPU time)" where the figure is the thread's CPU time of a busy machine (the tables label it so)."""
    return " (CPU time)" if row.cpu_time_reason(metric) else ""


def _fastest_accurate(data: ReportData, offline: list[ReportRow], online: list[ReportRow]) -> list[Finding]:
    """The fastest batch-1 method per hardware whose MSE is within MSE_KEPT × the baseline's and that
    lost none of the laps its baseline completed: the answer to "what do I deploy", always said (where no
    method qualifies or a candidate's timing stayed disturbed, why)."""
    findings = []
    for hardware in dict.fromkeys(r.hardware for r in offline):
        label = f"Fastest within {MSE_KEPT:g}× the baseline's MSE on {hardware}"
        here = [r for r in offline if r.hardware == hardware and _keeps_accuracy(data, r, online)]
        row = best(here, "latency_ms")
        if row is None:
            if any(baseline_of(data, r) is not None for r in offline if r.hardware == hardware):
                findings.append(Finding(label, f"none: no timed method keeps the MSE within {MSE_KEPT:g}× the "
                                               f"baseline's and the laps the baseline completes"))
            continue
        if issue := timing_issue(here, "latency_ms"):
            findings.append(Finding(label, f"not drawn: {issue}; rerun", _rerun_timing(data),
                                    "when the machine is quieter"))
            continue
        findings.append(Finding(label, _accurate_text(data, row, online)))
    return findings


def _accurate_text(data: ReportData, row: ReportRow, online: list[ReportRow]) -> str:
    base = baseline_of(data, row)
    laps = [r for r in online if _same_method(r, row) and r.get("lap_completed") is not None]
    completed = sum(bool(r.get("lap_completed")) for r in laps)
    lost = f" (the baseline lost the other {len(laps) - completed} too)" if completed < len(laps) else ""
    return (f"{method_label(row, data)} — {format_value('latency_ms', row.get('latency_ms'))} ms per image"
            f"{_clock(row, 'latency_ms')}"
            f"{_versus(data, row, 'latency_ms', 'faster')}, MSE {row.get('mse') / base.get('mse'):.2f}× "
            f"{data.baseline}'s" + (f", {completed} of {len(laps)} laps completed{lost}" if laps else ""))


def _keeps_accuracy(data: ReportData, row: ReportRow, online: list[ReportRow]) -> bool:
    """MSE within MSE_KEPT × the baseline's, and no lap lost where the baseline completed its own (a circuit
    the baseline loses too says nothing against the method)."""
    base = baseline_of(data, row)
    if base is None or not isinstance(row.get("mse"), (int, float)) or not base.get("mse"):
        return False
    lost = any(r.get("lap_completed") is False and _baseline_lap_completed(data, r)
               for r in online if _same_method(r, row))
    return row.get("mse") <= MSE_KEPT * base.get("mse") and not lost


def _baseline_lap_completed(data: ReportData, lap: ReportRow) -> bool:
    """Whether the baseline completed its lap where `lap` was driven (True when it has none there)."""
    base = baseline_of(data, lap)
    return base is None or base.get("lap_completed") is not False


def _same_method(lap: ReportRow, row: ReportRow) -> bool:
    return (lap.model, lap.strategy, lap.hardware) == (row.model, row.strategy, row.hardware)


def _closed_loop(data: ReportData, rows: list[ReportRow]) -> list[Finding]:
    findings = []
    for hardware, place in dict.fromkeys((r.hardware, r.place) for r in rows):
        here = [r for r in rows if r.hardware == hardware and r.place == place and r.status == "ok"]
        parts = _lap_parts(data, here)
        if parts:
            findings.append(Finding(f"Closed loop on {place} ({hardware})", "; ".join(parts)))
    return findings


def _lap_parts(data: ReportData, rows: list[ReportRow]) -> list[str]:
    parts = []
    completed = [r for r in rows if r.get("lap_completed") is True]
    lap = best(completed, "lap_seconds")
    if lap is not None:
        parts.append(f"fastest lap {method_label(lap, data)} ({format_value('lap_seconds', lap.get('lap_seconds'))} s)")
    steady = best(completed, "position_deviation_mae_m")
    if steady is not None:
        value = format_value("position_deviation_mae_m", steady.get("position_deviation_mae_m"))
        parts.append(f"closest to the line {method_label(steady, data)} ({value} m)")
    lost = [r for r in rows if r.get("lap_completed") is False]
    if lost:
        parts.append("lost the lap: " + ", ".join(
            f"{method_label(r, data)} ({format_value('percentage_completed', r.get('percentage_completed'))})"
            + (f" {UNSTABLE} replaying an unstable timing" if r.unstable_reason("latency_ms") else "")
            for r in lost))
    elif completed:
        parts.append("every model completed the lap")
    return parts


def _not_run(data: ReportData, status: str, label: str) -> list[Finding]:
    rows = [r for r in data.rows if r.status == status]
    if not rows:
        return []
    by_reason: dict[str, list[ReportRow]] = {}
    for row in rows:
        by_reason.setdefault(row.reason, []).append(row)
    text = "; ".join(_cells_with_reason(data, reason, alike) for reason, alike in by_reason.items())
    return [Finding(f"{label} ({len(rows)})", text)]


def _cells_with_reason(data: ReportData, reason: str, rows: list[ReportRow]) -> str:
    """'reason — 3 cells: a, b on cuda' (one cell: 'a on cuda, montreal cw (online): reason')."""
    if len(rows) == 1:
        r = rows[0]
        return f"{method_label(r, data)} on {r.hardware}, {r.place} ({r.kind}): {reason}"
    methods = ", ".join(dict.fromkeys(method_label(r, data) for r in rows))
    hardware = ", ".join(dict.fromkeys(r.hardware for r in rows))
    return f"{reason} — {len(rows)} cells: {methods} on {hardware}"


def _ties(data: ReportData, rows: list[ReportRow], winner: ReportRow, metric: str) -> str:
    """' (a, b read the same)' for the other strategies whose value reads the same as the winner's, to the
    digits shown (a difference below them, as the MSE's against the baseline, is said apart: "tied" with a
    non-zero difference beside it read as a contradiction)."""
    shown = format_value(metric, winner.get(metric))
    same = dict.fromkeys(method_label(r, data) for r in rows
                         if r.get(metric) is not None and format_value(metric, r.get(metric)) == shown)
    same.pop(method_label(winner, data), None)
    return f" ({', '.join(same)} read{'s' if len(same) == 1 else ''} the same)" if same else ""


SPREAD = {"latency_ms": ("latency_p10_ms", "latency_p90_ms"), "throughput_ips": ("throughput_p10_ips", "throughput_p90_ips")}


def _within_spread(data: ReportData, rows: list[ReportRow], winner: ReportRow, metric: str) -> str:
    """' (a, b within its spread)' for the others whose figure lies between the winner's 10th and 90th
    percentiles: the timing noise does not tell them apart (two definitions of one network, timed
    minutes apart, were a winner and a loser)."""
    low, high = (winner.get(name) for name in SPREAD[metric])
    if low is None or high is None:
        return ""
    low, high = min(low, high), max(low, high)
    close = dict.fromkeys(method_label(r, data) for r in rows if r is not winner and r.get(metric) is not None
                          and low <= r.get(metric) <= high)
    close.pop(method_label(winner, data), None)
    return f" ({', '.join(close)} within its spread)" if close else ""


def _versus(data: ReportData, row: ReportRow, metric: str, word: str) -> str:
    base = baseline_of(data, row)
    if base is None or base is row or not row.get(metric) or base.get(metric) is None:
        return ""
    return f", {base.get(metric) / row.get(metric):.2f}× {word} than {data.baseline}"


def _mse_delta(data: ReportData, row: ReportRow) -> str:
    base = baseline_of(data, row)
    if base is None or base is row or base.get("mse") is None:
        return ""
    delta = row.get("mse") - base.get("mse")
    return f" ({'+' if delta >= 0 else '−'}{abs(delta):.2g} against {data.baseline})"
