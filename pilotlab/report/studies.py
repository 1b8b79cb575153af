"""Published claims checked against a report's own figures.

A recipe can ask for a comparison (`report: {compare_with: study2022}`); each claim is a function of
the report's rows that says whether the claim holds on our setup, with our figures. The verdicts are
computed, never written by hand, so a rerun on other hardware updates them. A claim about speed is
"not testable here" when a timing it rests on stayed disturbed (`timing_issue`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from matrix.registry import Registry

if TYPE_CHECKING:   # the rows are read only when a report is written; a recipe names a study to plan
    from pilotlab.report.data import ReportData, ReportRow

Verdict = Literal["holds", "does not hold", "not testable here"]


@dataclass(frozen=True)
class ClaimCheck:
    claim: str          # what the study says, with its figures
    verdict: Verdict
    found: str          # what we measured


Check = Callable[["ReportData"], ClaimCheck]
STUDIES: Registry[tuple[str, tuple[Check, ...]]] = Registry("study")   # name -> (title, checks)


def compare(data: ReportData, study: str) -> tuple[str, list[ClaimCheck]]:
    title, checks = STUDIES.get(study)
    return title, [check(data) for check in checks]


# --- reading the rows ------------------------------------------------------------------------------

def _is_its_name(row: ReportRow) -> bool:
    """A row named after a built-in strategy was made by it: a recipe may give a study's name to another
    strategy (`static_quant: ...` cannot, `tensorrt_int8: {use: onnxruntime_int8}` can), not the study's row."""
    from pilotlab.strategies import STRATEGIES   # (the package: it registers every strategy)
    return row.runs is None or row.runs == row.strategy or row.strategy not in STRATEGIES


def _offline(data: ReportData) -> dict[str, ReportRow]:
    """strategy -> its measured offline row on the first CPU hardware profile of the report."""
    rows = [r for r in data.of_kind("offline") if r.status == "ok" and _is_its_name(r)]
    cpu = next((r.hardware for r in rows if r.hardware.startswith("cpu")), None)
    return {r.strategy: r for r in rows if r.hardware == cpu}


def _laps(data: ReportData, circuit: str) -> dict[str, ReportRow]:
    rows = [r for r in data.of_kind("online") if r.status == "ok" and r.circuit == circuit and _is_its_name(r)]
    cpu = next((r.hardware for r in rows if r.hardware.startswith("cpu")), None)
    return {r.strategy: r for r in rows if r.hardware == cpu}


def _ratio(rows: dict[str, ReportRow], strategy: str, metric: str) -> float | None:
    """The baseline's metric over the strategy's (size ×, speed-up ×)."""
    base, row = rows.get("baseline"), rows.get(strategy)
    if base is None or row is None or not base.get(metric) or not row.get(metric):
        return None
    return base.get(metric) / row.get(metric)


def _clearly_faster(rows: dict[str, ReportRow], strategy: str) -> bool:
    """Faster beyond the timing noise: even the strategy's slow runs (its 90th percentile) beat the
    baseline's median. Without percentiles, a 10 % margin on the medians."""
    base, row = rows["baseline"], rows[strategy]
    slow = row.get("latency_p90_ms") or 1.1 * row.get("latency_ms")
    return slow < base.get("latency_ms")


def _lowest(claim: str, data: ReportData, strategy: str, metric: str, label: str, style: str) -> ClaimCheck:
    """Holds when `strategy` has the lowest `metric` of the offline rows."""
    rows = {s: r for s, r in _offline(data).items() if r.get(metric) is not None}
    if strategy not in rows:
        return _untestable(claim, f"no {strategy} offline row")
    if metric == "latency_ms" and (untrusted := _untrusted_timing(claim, rows.values())):
        return untrusted
    best = min(rows, key=lambda s: rows[s].get(metric))
    return ClaimCheck(claim, _verdict(best == strategy), f"{label}: {best} ({style.format(rows[best].get(metric))}); "
                                                         f"{strategy} {style.format(rows[strategy].get(metric))}")


def _untrusted_timing(claim: str, rows) -> ClaimCheck | None:
    """A "not testable here" verdict when the latencies of `rows` cannot be compared, else None."""
    from pilotlab.report.data import timing_issue
    issue = timing_issue([r for r in rows if r is not None])
    return _untestable(claim, f"timings not to be trusted: {issue}") if issue else None


def _untestable(claim: str, missing: str) -> ClaimCheck:
    return ClaimCheck(claim, "not testable here", missing)


def _verdict(holds: bool) -> Verdict:
    return "holds" if holds else "does not hold"


# --- the 2022 study (JdeRobot, "Optimizing deep learning models for end-to-end driving") -----------

POST_TRAINING_INT8 = ("dynamic_quant", "static_quant", "onnxruntime_int8")


def static_quant_smaller(data: ReportData) -> ClaimCheck:
    claim = "Static quantization makes PilotNet about 4× smaller (PyTorch: 6.12 MB -> 1.61 MB, 3.8×)."
    ratio = _ratio(_offline(data), "static_quant", "size_mb")
    if ratio is None:
        return _untestable(claim, _no_rows(_offline(data), "static_quant"))
    return ClaimCheck(claim, _verdict(ratio >= 3.5), f"static_quant is {ratio:.2f}× smaller than the baseline")


def int8_keeps_mse(data: ReportData) -> ClaimCheck:
    claim = ("Post-training quantization keeps the offline MSE about unchanged (PyTorch: baseline 0.0788, "
             "dynamic 0.0784, static 0.0788).")
    rows = _offline(data)
    base = rows.get("baseline")
    measured = [(s, rows[s].get("mse")) for s in POST_TRAINING_INT8 if s in rows and rows[s].get("mse") is not None]
    if base is None or base.get("mse") is None or not measured:
        return _untestable(claim, _no_rows(rows, "/".join(POST_TRAINING_INT8)))
    changes = {s: (mse - base.get("mse")) / base.get("mse") for s, mse in measured}
    worst = max(changes, key=lambda s: abs(changes[s]))
    found = ", ".join(f"{s} {100 * c:+.1f}%" for s, c in changes.items())
    return ClaimCheck(claim, _verdict(abs(changes[worst]) <= 0.10),
                      f"MSE change against the baseline ({base.get('mse'):.4g}): {found}")


def prune_quant_lowest_mse(data: ReportData) -> ClaimCheck:
    claim = "Prune + quantization has the lowest MSE of all (0.0672 vs the baseline's 0.0788)."
    return _lowest(claim, data, "prune_quant", "mse", "lowest MSE", "{:.4g}")


def local_prune_fastest(data: ReportData) -> ClaimCheck:
    claim = "Local pruning has the best CPU inference time (2.09 ms vs the baseline's 2.18 ms)."
    return _lowest(claim, data, "local_prune", "latency_ms", "fastest", "{:.3g} ms")


def unstructured_pruning_no_speedup(data: ReportData) -> ClaimCheck:
    claim = "Unstructured weight pruning shrinks nothing on disk and brings no latency improvement."
    rows = _offline(data)
    speedups = {s: _ratio(rows, s, "latency_ms") for s in ("local_prune", "global_prune")}
    speedups = {s: v for s, v in speedups.items() if v is not None}
    if not speedups:
        return _untestable(claim, "no local_prune / global_prune offline rows")
    if untrusted := _untrusted_timing(claim, [rows["baseline"], *(rows[s] for s in speedups)]):
        return untrusted
    faster = [s for s in speedups if _clearly_faster(rows, s)]
    found = ", ".join(f"{s} {v:.2f}× the baseline's speed" for s, v in speedups.items())
    noise = "; faster beyond the timing noise (p90 below the baseline's median): " + (", ".join(faster) or "neither")
    return ClaimCheck(claim, _verdict(not faster), found + noise)


def dynamic_quant_slower_in_pytorch(data: ReportData) -> ClaimCheck:
    claim = "PyTorch dynamic-range quantization was slower than the baseline (3.17 ms vs 2.18 ms)."
    rows = _offline(data)
    speedup = _ratio(rows, "dynamic_quant", "latency_ms")
    if speedup is None:
        return _untestable(claim, _no_rows(rows, "dynamic_quant"))
    if untrusted := _untrusted_timing(claim, [rows["baseline"], rows["dynamic_quant"]]):
        return untrusted
    return ClaimCheck(claim, _verdict(speedup < 1.0),
                      f"dynamic_quant runs at {speedup:.2f}× the baseline's speed (ONNX Runtime, MatMul/Gemm only)")


def optimized_models_complete_the_lap(data: ReportData) -> ClaimCheck:
    claim = ("On SimpleCircuit the optimized PyTorch models complete the lap "
             "(local prune, global prune, QAT, prune + quantization).")
    laps = _laps(data, "simple_circuit")
    study = [s for s in ("local_prune", "global_prune", "qat", "prune_quant") if s in laps]
    if not study:
        return _untestable(claim, "no laps of those strategies on simple_circuit")
    lost = [s for s in study if not laps[s].get("lap_completed")]
    found = "all completed" if not lost else f"lost the lap: {', '.join(lost)}"
    return ClaimCheck(claim, _verdict(not lost), f"{found} ({len(study)} strategies driven)")


def fastest_drives_as_well(data: ReportData) -> ClaimCheck:
    claim = ("The fastest models drive the lap at least as well as the original (TF-TRT: higher brain "
             "frequency, BehaviorMetrics position deviation MAE 5.06 vs 7.41).")
    offline, laps = _offline(data), _laps(data, "simple_circuit")
    timed = {s: r.get("latency_ms") for s, r in offline.items() if r.get("latency_ms") is not None and s in laps}
    base = laps.get("baseline")
    metric = "bm_position_deviation_mae" if base is not None and base.get("bm_position_deviation_mae") else \
        "position_deviation_mae_m"
    if not timed or base is None or base.get(metric) is None:
        return _untestable(claim, "no offline latency and laps of the same strategies on simple_circuit")
    if untrusted := _untrusted_timing(claim, [offline[s] for s in timed]):
        return untrusted
    fastest = min(timed, key=timed.get)
    row = laps[fastest]
    deviation, base_deviation = row.get(metric), base.get(metric)
    holds = _drives_as_far(row, base) and deviation is not None and deviation <= 1.1 * base_deviation
    unit = " (BehaviorMetrics' 1000^d score)" if metric.startswith("bm_") else " m"
    found = (f"fastest offline: {fastest}; lap {_lap_said(row)}, deviation {deviation:.3g} vs the baseline's "
             f"{base_deviation:.3g}{unit} (its lap {_lap_said(base)})" if deviation is not None else
             f"fastest offline: {fastest}; no deviation measured")
    return ClaimCheck(claim, _verdict(holds), found)


def _drives_as_far(row: ReportRow, base: ReportRow) -> bool:
    """The row completes the lap, or goes at least as far as the baseline, which lost it too."""
    if row.get("lap_completed"):
        return True
    return not base.get("lap_completed") and (row.get("percentage_completed") or 0) >= (base.get("percentage_completed") or 0)


def _lap_said(row: ReportRow) -> str:
    share = row.get("percentage_completed")
    return "completed" if row.get("lap_completed") else f"lost at {share:.0f} %" if share is not None else "lost"


STUDY_BASELINE_MS = 124.0   # the original PilotNet's inference time in the study's closed loop


def _tolerance_cells(data: ReportData, circuit: str) -> dict[tuple[str, str], dict[str, ReportRow]]:
    """(hardware, direction) -> strategy -> its network lap on `circuit` in that direction, where the
    baseline's latency tolerance was searched there (the other strategies' laps with or without a search
    of their own; a direction is compared with itself)."""
    cells: dict[tuple[str, str], dict[str, ReportRow]] = {}
    for r in data.of_kind("online"):
        if r.status == "ok" and r.circuit == circuit and r.model != "reference" and _is_its_name(r):
            cells.setdefault((r.hardware, r.direction or ""), {})[r.strategy] = r
    return {place: rows for place, rows in cells.items() if "baseline" in rows and rows["baseline"].tolerance}


def _budget(row: ReportRow) -> tuple[float | None, str]:
    """(the largest total latency at which the lap is kept: own + tolerance, None if lost at its own;
    that in words). A lap whose tolerance was not searched: (None, its own latency and its lap)."""
    own, tolerance = row.get("mean_inference_ms") or 0.0, row.get("latency_tolerance_ms")
    if not row.tolerance:
        return None, f"{own:.3g} ms, lap {_lap_said(row)} (its tolerance not searched)"
    if tolerance is None:
        return None, f"{own:.3g} ms, lost even at that"
    more = "≥ " if row.tolerance_at_least else ""
    return own + tolerance, f"{own:.3g} ms, keeps it up to {more}{own + tolerance:.0f} ms in all (+{tolerance:.0f} ms)"


def _bm_figures(row: ReportRow) -> str:
    share, deviation = row.get("bm_percentage_completed"), row.get("bm_position_deviation_mae")
    figures = ([f"{share:.0f} % completed"] if share is not None else []) + \
        ([f"deviation MAE {deviation:.3g}"] if deviation is not None else [])
    return f" (BehaviorMetrics: {', '.join(figures)})" if figures else ""


def montreal_is_hard(data: ReportData) -> ClaimCheck:
    claim = (f"The original PilotNet ({STUDY_BASELINE_MS:.0f} ms per inference) does not complete Montreal; the fast "
             "(TensorRT) versions do.")
    cells = _tolerance_cells(data, "montreal")
    if not cells:
        return _untestable(claim, "no latency tolerance searched for the baseline's lap on montreal (laps at this "
                                  "host's latency alone cannot say what 124 ms would do)")
    # The profile that gives the baseline the study's latency if there is one, else the first; its first
    # direction (cw before ccw)
    place = min(cells, key=lambda p: (abs((cells[p]["baseline"].get("mean_inference_ms") or 0) - STUDY_BASELINE_MS),
                                      p[1] != "cw", p))
    rows, base = cells[place], cells[place]["baseline"]
    hardware = f"{place[0]} (montreal {place[1]})" if place[1] else place[0]
    budget, said = _budget(base)
    base_loses = budget is None or budget < STUDY_BASELINE_MS
    own = base.get("mean_inference_ms") or 0.0
    latency = {s: r.get("mean_inference_ms") or 0.0 for s, r in rows.items() if s != "baseline"}
    # the versions at half the baseline's latency or less, else those faster at all (never a slower one)
    fast = {s: rows[s] for s, ms in latency.items() if ms <= own / 2} or {s: rows[s] for s, ms in latency.items() if ms < own}
    if not fast:
        return _untestable(claim, f"no version faster than the baseline ({own:.3g} ms) was driven on montreal on {hardware}")
    kept = [s for s, r in fast.items() if r.get("lap_completed")]
    found = (f"on {hardware}: baseline {said}{_bm_figures(base)}, so at {STUDY_BASELINE_MS:.0f} ms it "
             f"{'loses' if base_loses else 'keeps'} Montreal; faster versions at their own latency: " +
             "; ".join(f"{s} {_budget(r)[1]}{_bm_figures(r)}" for s, r in fast.items()))
    return ClaimCheck(claim, _verdict(base_loses and len(kept) == len(fast)), found)


def tensorrt_fastest(data: ReportData) -> ClaimCheck:
    claim = "TensorRT int8 is about 33× faster than the original model (on a GTX 1050)."
    tensorrt = [r for r in data.of_kind("offline") if _is_tensorrt(r)]
    # the int8 engine where the recipe has one (tensorrt_int8), else the fastest TensorRT row
    rows = sorted((r for r in tensorrt if r.status == "ok" and r.get("latency_ms")),
                  key=lambda r: (not _is_int8(r), r.get("latency_ms")))
    if not rows:
        reason = next((r.reason for r in tensorrt if r.reason), "no tensorrt rows")
        return _untestable(claim, reason)
    gpu = rows[0].hardware
    base = next((r for r in data.of_kind("offline") if r.strategy == "baseline" and r.hardware == gpu
                 and r.status == "ok" and r.get("latency_ms")), None)
    if base is None or not rows[0].get("latency_ms"):
        return _untestable(claim, f"no baseline latency on {gpu} to compare tensorrt with")
    if untrusted := _untrusted_timing(claim, [base, rows[0]]):
        return untrusted
    speedup = base.get("latency_ms") / rows[0].get("latency_ms")
    return ClaimCheck(claim, _verdict(speedup >= 16.0),    # "about 33×": at least half of it
                      f"{rows[0].strategy} on {gpu}: {rows[0].get('latency_ms'):.3g} ms, {speedup:.1f}× the "
                      "baseline's speed")


def _is_tensorrt(row: ReportRow) -> bool:
    """Made by the tensorrt strategy, whatever the recipe named it (by its name where that is not known)."""
    return row.runs == "tensorrt" if row.runs is not None else row.strategy.startswith("tensorrt")


def _is_int8(row: ReportRow) -> bool:
    return row.options.get("precision") == "int8" if row.runs is not None else "int8" in row.strategy


def _missing_reason(data: ReportData, strategy: str) -> str:
    """Why a strategy has no measured offline row: its own reason (not installed...) where given."""
    return next((r.reason for r in data.rows if r.strategy == strategy and r.reason),
                _no_rows(_offline(data), strategy))


def _no_rows(rows: dict, strategies: str) -> str:
    """Which of the rows a claim needs are missing: `strategies` ("a/b": any of them) and the baseline's
    (the outside test read "no static_quant and baseline offline rows" of a report with the baseline)."""
    missing = [name for name in (strategies, "baseline") if not any(s in rows for s in name.split("/"))]
    return f"no measured offline row of {' nor '.join(missing) or strategies}"


def dynamic_range_smaller_at_equal_mse(data: ReportData) -> ClaimCheck:
    claim = "TF Lite dynamic-range quantization makes PilotNet about 4× smaller at about the same MSE."
    rows = _offline(data)
    base, row = rows.get("baseline"), rows.get("litert_dynamic_range")
    ratio = _ratio(rows, "litert_dynamic_range", "size_mb")
    if ratio is None or base.get("mse") is None or row.get("mse") is None:
        return _untestable(claim, _missing_reason(data, "litert_dynamic_range"))
    change = (row.get("mse") - base.get("mse")) / base.get("mse")
    return ClaimCheck(claim, _verdict(ratio >= 3.5 and abs(change) <= 0.10),
                      f"litert_dynamic_range (LiteRT) is {ratio:.2f}× smaller than the baseline, MSE "
                      f"{100 * change:+.1f}% against the baseline's {base.get('mse'):.4g}")


def full_integer_unusable(data: ReportData) -> ClaimCheck:
    claim = ("Integer-only quantization is unusable for a regression network "
             "(TF Lite \"Integer only Q\", int8 input and output: MSE 28,157).")
    rows = _offline(data)
    base, row = rows.get("baseline"), rows.get("litert_full_int8")
    if base is None or row is None or not base.get("mse") or row.get("mse") is None:
        return _untestable(claim, _missing_reason(data, "litert_full_int8"))
    ratio = row.get("mse") / base.get("mse")
    return ClaimCheck(claim, _verdict(ratio > 10.0),
                      f"litert_full_int8 MSE {row.get('mse'):.4g}, {ratio:.2f}× the baseline's "
                      f"{base.get('mse'):.4g}, with its int8 output dequantized by the scale stored in the "
                      "model; read raw it is off by that scale (the optimize job's raw_output_mse)")


LITERT_ROWS = ("litert", "litert_dynamic_range", "litert_float16", "litert_int8", "litert_full_int8", "prune_litert",
               "prune_litert_int8", "qat_litert_int8", "pqat_litert_int8", "cqat_litert_int8", "pcqat_litert_int8")


def clustering_lowest_mse(data: ReportData) -> ClaimCheck:
    claim = ("The cluster-preserving collaborative optimizations have the lowest MSE of the TF Lite rows "
             "(PCQAT 0.0392, CQAT 0.0394; TF Lite baseline 0.0411, QAT 0.0421, PQAT 0.0437).")
    rows = {s: r for s, r in _offline(data).items() if s in LITERT_ROWS and r.get("mse") is not None}
    if not {"cqat_litert_int8", "pcqat_litert_int8"} & set(rows):
        return _untestable(claim, _missing_reason(data, "pcqat_litert_int8"))
    ranked = sorted(rows, key=lambda s: rows[s].get("mse"))
    found = "lowest MSE of the study's TF Lite rows on LiteRT: " + ", ".join(f"{s} {rows[s].get('mse'):.4g}" for s in ranked[:3])
    return ClaimCheck(claim, _verdict(ranked[0] in ("cqat_litert_int8", "pcqat_litert_int8")), found)


def pruning_shrinks_only_compressed(data: ReportData) -> ClaimCheck:
    claim = ("Weight pruning leaves the model as large as the TF Lite baseline (64.9 MB both); what it buys is "
             "compression (up to 6× smaller compressed, 10× with quantization).")
    rows = _offline(data)
    dense, pruned = rows.get("litert"), rows.get("prune_litert")
    if dense is None or pruned is None or not all(r.get(m) for r in (dense, pruned) for m in ("size_mb", "size_gz_mb")):
        return _untestable(claim, _missing_reason(data, "prune_litert") if pruned is None else
                           "no litert row (LiteRT fp32, the study's TF Lite baseline): add litert to the matrix"
                           if dense is None else "no raw and compressed sizes of litert and prune_litert")
    raw = pruned.get("size_mb") / dense.get("size_mb")
    packed = dense.get("size_gz_mb") / pruned.get("size_gz_mb")
    found = (f"prune_litert {pruned.get('size_mb'):.3g} MB raw ({raw:.2f}× litert's), "
             f"{pruned.get('size_gz_mb'):.3g} MB gzip-compressed ({packed:.2f}× smaller than litert's "
             f"{dense.get('size_gz_mb'):.3g} MB)")
    if (quantized := rows.get("prune_litert_int8")) is not None and quantized.get("size_gz_mb"):
        found += f"; prune_litert_int8 {dense.get('size_gz_mb') / quantized.get('size_gz_mb'):.2f}× smaller compressed"
    return ClaimCheck(claim, _verdict(abs(raw - 1) <= 0.02 and packed >= 1.25), found)


STUDIES.add("study2022", ("Compared with the 2022 study", (
    static_quant_smaller, int8_keeps_mse, prune_quant_lowest_mse, local_prune_fastest,
    unstructured_pruning_no_speedup, dynamic_quant_slower_in_pytorch, optimized_models_complete_the_lap,
    fastest_drives_as_well, montreal_is_hard, tensorrt_fastest, dynamic_range_smaller_at_equal_mse,
    full_integer_unusable, clustering_lowest_mse, pruning_shrinks_only_compressed)))
