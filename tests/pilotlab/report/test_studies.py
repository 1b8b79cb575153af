"""The 2022 study's claims, checked against a report's rows: the study's own figures must confirm
what the study says, and our kind of figures must be judged with the timing noise in mind."""
from pilotlab.report import ReportData
from pilotlab.report.studies import compare
from tests.pilotlab.report.toy import offline_row, offline_rows, online_row, small_dict


def verdicts(rows: list[dict]) -> dict[str, tuple[str, str]]:
    _, checks = compare(ReportData.from_dict(small_dict(rows)), "study2022")
    return {check.claim.split(" (")[0]: (check.verdict, check.found) for check in checks}


def test_the_studys_own_offline_figures_confirm_its_offline_claims():
    found = verdicts(offline_rows("cpu1"))                      # the study's sizes, MSEs and latencies
    for claim in ("Static quantization makes PilotNet about 4× smaller",
                  "Post-training quantization keeps the offline MSE about unchanged",
                  "Prune + quantization has the lowest MSE of all",
                  "Local pruning has the best CPU inference time",
                  "Unstructured weight pruning shrinks nothing on disk and brings no latency improvement.",
                  "PyTorch dynamic-range quantization was slower than the baseline"):
        assert found[claim][0] == "holds", (claim, found[claim])
    assert found["The original PilotNet does not complete Montreal; the fast TensorRT versions do."][0] == \
        "not testable here"


def pruning(local_ms: float, local_p90_ms: float) -> list[dict]:
    return [offline_row("baseline", size_mb=6.1, latency_ms=2.62, latency_p90_ms=3.15),
            offline_row("local_prune", size_mb=6.1, latency_ms=local_ms, latency_p90_ms=local_p90_ms)]


def test_a_speed_up_within_the_timing_noise_is_no_speed_up():
    claim = "Unstructured weight pruning shrinks nothing on disk and brings no latency improvement."
    verdict, found = verdicts(pruning(2.30, 2.70))[claim]      # 1.14× on the medians, but its p90 is slower
    assert verdict == "holds" and "local_prune 1.14×" in found and "neither" in found
    verdict, found = verdicts(pruning(1.50, 1.80))[claim]      # even its slow runs beat the baseline's median
    assert verdict == "does not hold" and found.endswith("median): local_prune")


def test_laps_decide_the_closed_loop_claims():
    rows = [offline_row("baseline", latency_ms=2.6), offline_row("qat", latency_ms=0.5),
            online_row("baseline", lap_completed=True, position_deviation_mae_m=0.07),
            online_row("qat", lap_completed=True, position_deviation_mae_m=0.066),
            online_row("local_prune", lap_completed=False, position_deviation_mae_m=0.9)]
    found = verdicts(rows)
    assert found["On SimpleCircuit the optimized PyTorch models complete the lap"] == \
        ("does not hold", "lost the lap: local_prune (2 strategies driven)")
    verdict, text = found["The fastest models drive the lap at least as well as the original"]
    assert verdict == "holds" and "fastest offline: qat" in text


def test_tensorrt_is_judged_by_its_speed_up_on_the_same_gpu():
    claim = "TensorRT int8 is about 33× faster than the original model"
    slow = [offline_row("baseline", "cuda", latency_ms=1.0), offline_row("tensorrt", "cuda", latency_ms=0.2)]
    fast = [offline_row("baseline", "cuda", latency_ms=1.0), offline_row("tensorrt", "cuda", latency_ms=0.04)]
    assert verdicts(slow)[claim] == ("does not hold", "tensorrt on cuda: 0.2 ms, 5.0× the baseline's speed")
    assert verdicts(fast)[claim][0] == "holds"
    missing = [offline_row("tensorrt", "cuda", status="not_applicable", reason="needs a CUDA GPU")]
    assert verdicts(missing)[claim] == ("not testable here", "needs a CUDA GPU")


def test_no_verdict_is_drawn_from_an_unstable_timing():
    claim = "PyTorch dynamic-range quantization was slower than the baseline"
    disturbed = "only 4 of 24 calls (17 %) ran with no thread of this process waiting for a CPU"
    rows = [offline_row("baseline", latency_ms=2.6, unstable={"latency_ms": disturbed}),
            offline_row("dynamic_quant", latency_ms=0.5)]
    verdict, found = verdicts(rows)[claim]
    assert verdict == "not testable here"
    assert found == f"timings not to be trusted: baseline (cpu1): unstable: {disturbed}"
    rows[0].pop("unstable")
    assert verdicts(rows)[claim][0] == "does not hold"
