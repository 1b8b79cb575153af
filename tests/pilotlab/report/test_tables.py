from pathlib import Path

from pilotlab.report import ReportData
from pilotlab.report.render import code_block, markdown_escape
from pilotlab.report.tables import build_tables, format_value, plus_minus, significant
from tests.pilotlab.report.toy import offline_row, repeated_rows, small_dict


def test_values_read_as_a_person_expects():
    assert format_value("mse", 0.07883577) == "0.0788"
    assert format_value("latency_ms", 2.177743) == "2.18"
    assert format_value("timing_blocks", 7.0) == "7" and format_value("timing_calls_discarded", 24.0) == "24"   # counts
    assert format_value("size_mb", 64.9173) == "64.9"
    assert format_value("throughput_ips", 12345.6) == "12,346"
    assert format_value("percentage_completed", 63.4) == "63 %"
    assert format_value("lap_completed", False) == "no"
    assert format_value("latency_ms", None) == "—"
    assert significant(0.000012345) == "0.0000123" and significant(1.2345e-7) == "1.23e-07" and significant(0.0) == "0"


def test_ratios_are_taken_against_the_baseline_of_the_same_table():
    rows = [offline_row("baseline", size_mb=6.12, mse=0.0788, latency_ms=2.18),
            offline_row("static_quant", size_mb=1.61, mse=0.0672, latency_ms=1.09),
            offline_row("qat", status="not_applicable", reason="needs a GPU")]
    [table] = build_tables(ReportData.from_dict(small_dict(rows)), "offline")
    by_method = {row.method: row for row in table.rows}
    size, speed, delta = (cell.text for cell in by_method["static_quant"].cells[-3:])
    assert (size, speed, delta) == ("3.80×", "2.00×", "−0.012")
    assert by_method["qat"].note == "not applicable: needs a GPU"
    assert table.headers[:5] == ("Model size (MB)", "Compressed (MB, gzip)", "MSE", "Inference time (ms)",
                                 "Throughput (images/s)")
    assert by_method["static_quant"].cells[4].text == "—" and by_method["static_quant"].cells[4].missing


def test_without_a_baseline_ratios_are_missing_and_the_table_says_why():
    rows = [offline_row("static_quant", size_mb=1.61, latency_ms=1.0), offline_row("qat", size_mb=1.6)]
    [table] = build_tables(ReportData.from_dict(small_dict(rows)), "offline")
    assert all(cell.text == "—" for row in table.rows for cell in row.cells[-3:])
    assert "No usable 'baseline' row for pilotnet" in table.notes[0]


def test_tables_split_by_hardware_and_circuit():
    online = [{"model": "pilotnet", "strategy": s, "hardware": h, "kind": "online", "circuit": c,
               "lap_completed": s == "baseline", "percentage_completed": 40.0, "lap_seconds": 50.0}
              for s in ("baseline", "qat") for h in ("cpu1", "cpu4") for c in ("montreal", "simple_circuit")]
    tables = build_tables(ReportData.from_dict(small_dict(online)), "online")
    assert [t.title for t in tables] == ["cpu1 · circuit montreal", "cpu1 · circuit simple_circuit",
                                         "cpu4 · circuit montreal", "cpu4 · circuit simple_circuit"]
    assert [row.cells[0].text for row in tables[0].rows] == ["✓ 50.0 s", "✗ 40 %"]


def test_markdown_escape_keeps_tables_and_html_intact():
    assert markdown_escape("a|b <script>x</script> *bold* dynamic_quant _x_") == \
        r"a\|b &lt;script&gt;x&lt;/script&gt; \*bold\* dynamic_quant \_x\_"
    assert markdown_escape("# title") == r"\# title" and markdown_escape("1. one") == r"1\. one"
    assert markdown_escape("1.5 ms, 2 cores") == "1.5 ms, 2 cores"
    assert code_block("a\n```\nb", "yaml") == "````yaml\na\n```\nb\n````"   # the fence outgrows the text's


def test_repeated_laps_show_the_mean_with_its_spread_and_a_single_lap_as_before():
    [table] = build_tables(ReportData.from_dict(small_dict(repeated_rows())), "online")
    texts = {row.method: [cell.text for cell in row.cells[:3]] for row in table.rows}
    assert texts["baseline"] == ["✓ 3/3, 47.8 ± 0.4 s", "8.95 ± 0.12", "0.213 ± 0.0004"]
    assert texts["qat"] == ["✗ 2/3, 87 %", "8.41 ± 0.30", "0.510 ± 0.000"]
    assert texts["local_prune"] == ["✓ 47.8 s", "8.95", "0.213"]
    baseline = table.rows[0].cells
    assert baseline[1].sort == 8.953 and "3 runs, min 8.81, max 9.05" in baseline[1].title
    assert table.rows[1].cells[4].missing and table.rows[1].cells[4].text == "—"   # not measured stays missing


def test_plus_minus_gives_the_std_the_decimals_of_the_mean():
    assert plus_minus("8.95", 0.1234) == "8.95 ± 0.12" and plus_minus("47.8", 0.41) == "47.8 ± 0.4"
    assert plus_minus("1,234", 56.7) == "1,234 ± 57" and plus_minus("0.213", 0.00004) == "0.213 ± 0.00004"
    assert plus_minus("20.0", 0.0) == "20.0 ± 0.0"


def test_a_table_whose_cells_all_share_one_reason_is_one_line():
    reason = "hardware 'cuda' needs a CUDA GPU; this host has none"
    rows = [offline_row(s, hardware="cuda", status="not_applicable", reason=reason)
            for s in ("baseline", "static_quant", "qat")] + [offline_row("baseline", size_mb=6.1)]
    tables = {t.hardware: t for t in build_tables(ReportData.from_dict(small_dict(rows)), "offline")}
    assert tables["cuda"].rows == ()
    assert tables["cuda"].notes == (f"not applicable for all 3 methods (baseline, static_quant, qat): {reason}",)
    assert len(tables["cpu1"].rows) == 1


def test_the_summary_groups_cells_that_were_not_run_by_reason():
    from pilotlab.report.summary import summarise
    rows = [offline_row(s, hardware="cuda", status="not_applicable", reason="no GPU") for s in ("baseline", "qat")]
    rows += [offline_row("static_quant", status="not_applicable", reason="no fbgemm")]
    [finding] = [f for f in summarise(ReportData.from_dict(small_dict(rows))) if f.label.startswith("Not applicable")]
    assert finding.label == "Not applicable (3)"
    assert finding.text == ("no GPU — 2 cells: baseline, qat on cuda; "
                            "static_quant on cpu1, simple_circuit (offline): no fbgemm")


DISTURBED = "only 4 of 24 calls (17 %) ran with no thread of this process waiting for a CPU in 4.2 s of measuring and re-measuring"


def timed_rows(**baseline_fields) -> list[dict]:
    baseline = {"latency_ms": 2.3, "latency_p10_ms": 2.2, "latency_p90_ms": 2.6, "threads": 2,
                "latency_runs": 1200, "throughput_ips": 900.0, **baseline_fields}
    return [offline_row("baseline", **baseline),
            offline_row("static_quant", latency_ms=0.4, latency_p10_ms=0.38, latency_p90_ms=0.45,
                        threads=2, latency_runs=5000, timing_other_cores=0.2, timing_calls_discarded=40)]


def test_timings_show_their_spread_and_how_they_were_measured():
    [table] = build_tables(ReportData.from_dict(small_dict(timed_rows())), "offline")
    base, quant = table.rows
    assert base.cells[3].text == "2.30 (2.20–2.60)" and quant.cells[-2].text == "5.75×"
    assert table.notes == ()
    assert table.method.startswith("Timings on 2 thread(s), one method at a time: inference time is the median of "
                                   "1,200–5,000 timed batch-1 calls per method")
    assert "(40 calls; other processes used 0.20 cores meanwhile)" in table.method


def test_an_unstable_timing_and_the_speed_ups_drawn_from_it_are_marked_with_the_reason():
    rows = timed_rows(unstable={"latency_ms": DISTURBED})
    [table] = build_tables(ReportData.from_dict(small_dict(rows)), "offline")
    base, quant = table.rows
    assert base.cells[3].text == "2.30 (2.20–2.60) ⚠" and DISTURBED in base.cells[3].title
    assert quant.cells[-2].text == "5.75× ⚠" and "baseline (cpu1): unstable" in quant.cells[-2].title
    assert table.notes == (f"⚠ baseline: inference time unstable: {DISTURBED}.",)


def test_a_timing_in_thread_cpu_time_is_labelled_with_the_reason_and_its_speed_ups_stand():
    busy = f"{DISTURBED}; so the figure is the CPU time of the thread that ran each call"
    rows = timed_rows(cpu_time={"latency_ms": busy})
    [table] = build_tables(ReportData.from_dict(small_dict(rows)), "offline")
    base, quant = table.rows
    assert base.cells[3].text == "2.30 (2.20–2.60) CPU" and f"CPU time: {busy}" in base.cells[3].title
    assert quant.cells[-2].text == "5.75×"
    assert table.notes == (f"CPU baseline: inference time in CPU time: {busy}.",)
    from pilotlab.report.recipe import row_from_result
    stored = row_from_result({"status": "ok", "value": {"latency_ms": 2.3, "cpu_time": {"latency_ms": busy,
                                                                                       "bogus": "x"}}}, Path("."))
    assert stored["cpu_time"] == {"latency_ms": busy}
    # outside test K11: the summary's "Fastest on cpu1" said its CPU-time figure as a plain one
    from pilotlab.report.summary import summarise
    rows = timed_rows()
    rows[1]["cpu_time"] = {"latency_ms": busy}
    fastest = next(f for f in summarise(ReportData.from_dict(small_dict(rows))) if f.label.startswith("Fastest on"))
    assert "0.400 ms per image (CPU time)" in fastest.text


def test_an_old_result_with_a_reference_kernel_time_still_reports():
    """Offline results stored before the reference kernel was removed carry `reference_ms`: left behind."""
    from pilotlab.report.data import pick_metrics
    assert pick_metrics({"latency_ms": 2.3, "reference_ms": 0.8}) == {"latency_ms": 2.3}


def test_no_summary_line_is_drawn_from_an_unstable_timing():
    from pilotlab.report.summary import summarise
    stable = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(timed_rows())))}
    assert stable["Fastest on cpu1"] == "static_quant — 0.400 ms per image, 5.75× faster than baseline"
    rows = timed_rows(unstable={"latency_ms": DISTURBED})
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(rows)))}
    assert found["Fastest on cpu1"].startswith(f"not drawn: baseline (cpu1): unstable: {DISTURBED}; rerun")
    assert found["Highest throughput on cpu1"].startswith("baseline — 900")     # throughput was not disturbed
    # with several models, whose baseline it was
    other = [{**row, "model": "mine"} for row in timed_rows()]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(rows + other)))}
    assert found["Fastest on cpu1"].startswith(f"not drawn: pilotnet · baseline (cpu1): unstable: {DISTURBED}; rerun")


def test_the_fastest_names_the_others_its_timing_noise_does_not_tell_apart():
    """Outside test: one network under two names, 0.403 and 0.339 ms (spreads 0.33-0.49 and 0.33-0.40),
    was "Fastest: q8b", as if it were faster."""
    from pilotlab.report.summary import summarise
    rows = [offline_row("baseline", latency_ms=2.0, latency_p10_ms=1.9, latency_p90_ms=2.2),
            offline_row("q8", latency_ms=0.403, latency_p10_ms=0.331, latency_p90_ms=0.491),
            offline_row("q8b", latency_ms=0.339, latency_p10_ms=0.325, latency_p90_ms=0.404)]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(rows)))}
    assert found["Fastest on cpu1"].startswith("q8b (q8 within its spread) — 0.339 ms per image")


def test_the_summary_names_the_fastest_method_that_keeps_its_accuracy_and_its_laps():
    from pilotlab.report.summary import summarise
    from tests.pilotlab.report.toy import online_row
    rows = [offline_row("baseline", mse=0.010, latency_ms=2.0), offline_row("worse", mse=0.013, latency_ms=0.1),
            offline_row("loses_a_lap", mse=0.010, latency_ms=0.2), offline_row("kept", mse=0.011, latency_ms=0.5),
            online_row("loses_a_lap", lap_completed=False), online_row("kept", lap_completed=True)]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(rows)))}
    assert found["Fastest on cpu1"].startswith("worse — 0.100 ms")
    assert found["Fastest within 1.2× the baseline's MSE on cpu1"] == (
        "kept — 0.500 ms per image, 4.00× faster than baseline, MSE 1.10× baseline's, 1 of 1 laps completed")


def test_the_deployment_line_is_always_said_and_judges_laps_against_the_baseline_s():
    """Outside test: the "Fastest within 1.2×" line vanished without a word when the baseline itself lost a
    circuit (every method lost it: none qualified), or when a method that could never qualify had a
    disturbed timing."""
    from pilotlab.report.summary import summarise
    from tests.pilotlab.report.toy import online_row
    label = "Fastest within 1.2× the baseline's MSE on cpu1"

    def lap(strategy, circuit, completed):
        return online_row(strategy, lap_completed=completed) | {"circuit": circuit}
    offline = [offline_row("baseline", mse=0.010, latency_ms=2.0), offline_row("int8", mse=0.010, latency_ms=0.5),
               offline_row("pruned", mse=0.019, latency_ms=0.2)]
    laps = [lap(s, "simple_circuit", s != "pruned") for s in ("baseline", "int8", "pruned")] + \
           [lap(s, "nurburgring", False) for s in ("baseline", "int8", "pruned")]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(offline + laps)))}
    assert found[label] == ("int8 — 0.500 ms per image, 4.00× faster than baseline, MSE 1.00× baseline's, "
                            "1 of 2 laps completed (the baseline lost the other 1 too)")
    disturbed = offline[:2] + [offline_row("pruned", mse=0.019, latency_ms=0.2, unstable={"latency_ms": DISTURBED})]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(disturbed + laps)))}
    assert found[label].startswith("int8 — 0.500 ms per image")          # the disturbed one could not qualify
    candidate = offline[:1] + [offline_row("int8", mse=0.010, latency_ms=0.5, unstable={"latency_ms": DISTURBED})]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(candidate + laps[:2])))}
    assert found[label].startswith(f"not drawn: int8 (cpu1): unstable: {DISTURBED}; rerun")


def test_values_that_read_the_same_are_not_called_a_tie_beside_their_difference():
    """Outside test: "Lowest MSE: dynamic_quant (tied with baseline) — 0.155 (−0.00035 against baseline)"."""
    from pilotlab.report.summary import summarise
    rows = [offline_row("baseline", mse=0.1550, latency_ms=2.0), offline_row("dq", mse=0.15465, latency_ms=1.0)]
    found = {f.label: f.text for f in summarise(ReportData.from_dict(small_dict(rows)))}
    assert found["Lowest MSE"] == "dq (baseline reads the same) — 0.155 (−0.00035 against baseline)"


def test_a_profile_s_simulation_table_says_where_the_reference_laps_are():
    """Replayed, the reference brains are driven on one CPU profile (planning/laps.py reference_cells)."""
    from tests.pilotlab.report.toy import online_row
    rows = [{**online_row("baseline", lap_completed=True), "hardware": "cpu"},
            {**online_row("explicit", lap_completed=True), "hardware": "cpu", "model": "reference"},
            {**online_row("baseline", lap_completed=True), "hardware": "cpu1"}]
    tables = {table.hardware: table for table in build_tables(ReportData.from_dict(small_dict(rows)), "online")}
    assert "The reference brains' laps are in the cpu table: replayed, they do not depend on the CPU profile." \
        in tables["cpu1"].notes
    assert not any("reference brains" in note for note in tables["cpu"].notes)
