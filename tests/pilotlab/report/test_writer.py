import csv
import json
import re

from markdown_it import MarkdownIt      # CommonMark + GFM tables, the way GitHub reads README.md (comes with rich)
from PIL import Image

from pilotlab.columns import BY_NAME
from pilotlab.report import ReportData, write_report
from tests.pilotlab.report.toy import draw_trajectory, offline_row, online_row, repeated_rows, small_dict

OFFLINE_HEADER = ("| Method | Model size (MB) | Compressed (MB, gzip) | MSE | Inference time (ms) | Throughput (images/s) "
                  "| Size × | Speed-up × | MSE Δ |")
ONLINE_HEADER = ("| Method | Lap | Average speed (m/s) | Position deviation MAE (m) | Brain iteration frequency (Hz) "
                 "| Mean inference time (ms) | Real-time factor |")


def render_markdown(text: str) -> str:
    return MarkdownIt("commonmark", {"html": True}).enable(["table", "strikethrough"]).render(text)


def table_shapes(html: str) -> list[list[int]]:
    """Cells per row of every rendered table."""
    return [[row.count("<td") + row.count("<th") for row in re.findall(r"<tr>(.*?)</tr>", table, re.S)]
            for table in re.findall(r"<table>(.*?)</table>", html, re.S)]


def read_csv(path):
    with path.open(newline="") as stream:
        return list(csv.DictReader(stream))


def test_every_file_is_written(study_report):
    data, paths = study_report
    for path in (paths.readme, paths.html, paths.csv, paths.json):
        assert path.is_file() and path.stat().st_size > 0
    assert set(paths.plots) == {"pareto", "ratios", "closed_loop", "training"}
    for png, svg in paths.plots.values():
        with Image.open(png) as image:
            assert image.format == "PNG" and image.width >= 500 and len(image.getcolors(1 << 20)) > 20
        assert svg.read_text().lstrip().startswith("<?xml") and "<svg" in svg.read_text()
    assert len(paths.trajectories) == 8 and all(p.parent.name == "trajectories" for p in paths.trajectories.values())


def test_csv_has_one_tidy_row_per_cell_with_status_reason_and_job_keys(study_report):
    data, paths = study_report
    rows = read_csv(paths.csv)
    assert len(rows) == len(data.rows)
    assert list(rows[0])[:9] == ["model", "strategy", "hardware", "circuit", "direction", "test_set", "kind",
                                 "status", "reason"]
    assert set(BY_NAME) <= set(rows[0]) and {"job_offline", "job_online", "trajectory"} <= set(rows[0])
    not_applicable = [r for r in rows if r["status"] == "not_applicable"]
    assert len(not_applicable) == 1 and not_applicable[0]["reason"].startswith("static quantization")
    assert all(not_applicable[0][name] == "" for name in BY_NAME)          # missing, never 0
    qat = next(r for r in rows if r["strategy"] == "qat" and r["hardware"] == "cpu1")
    assert qat["throughput_ips"] == "" and qat["mse"] == "0.0708" and qat["job_offline"] == "off-cpu1-qat"
    assert next(r for r in rows if r["kind"] == "online")["trajectory"].startswith("trajectories/")


def test_json_holds_the_run_description_and_rows_with_nulls(study_report):
    data, paths = study_report
    document = json.loads(paths.json.read_text())
    assert document["recipe"] == "study-2022" and document["host"]["cpu"] == "AMD EPYC 7B13"
    assert document["columns"]["latency_ms"] == {"unit": "ms", "doc": "batch-1 latency, median", "better": "lower"}
    failed = [r for r in document["rows"] if r["status"] == "failed"]
    assert len(failed) == 2 and all(r["mse"] is None and r["reason"] for r in failed)
    assert [p["epoch"] for p in document["histories"]["pilotnet"]] == list(range(1, 11))


def test_readme_has_the_study_shaped_tables_summary_and_plots(study_report):
    data, paths = study_report
    readme = paths.readme.read_text()
    assert readme.count(OFFLINE_HEADER) == 2 and readme.count(ONLINE_HEADER) == 2
    assert "### cpu4 · test set simple\\_circuit+montreal" not in readme       # intraword _ stays readable
    assert "### cpu4 · test set simple_circuit+montreal" in readme
    assert "| static_quant | *not applicable: static quantization kernels need 1 thread here* |" in readme
    assert "*failed: simulator crashed: pybullet lost its connection*" in readme
    assert "| qat | 1.61 | — | 0.0708 | 2.79 | — | 3.80× | 0.78× | −0.0080 |" in readme
    assert "| local_prune | ✗ 63 % | 7.74 | 1.42 | 20.0 | 2.10 | 0.960 |" in readme
    assert "- **Lowest MSE**: prune_quant — 0.0672 (−0.012 against baseline)" in readme
    assert "lost the lap: local_prune (63 %)" in readme
    for name in ("pareto", "ratios", "closed_loop", "training"):
        assert f"](plots/{name}.png)" in readme
    assert "- **Host**: AMD EPYC 7B13, 2 cores; GPU: none" in readme
    summary = [line for line in readme.splitlines() if line.startswith("- **")][:5]
    assert [line.split("**")[1] for line in summary] == ["Date", "Host", "Versions", "Cells", "Baseline"], summary
    assert "pilotlab 0.1.0, torch 2.13.0, onnxruntime 1.22.0" in readme
    assert "```yaml\nname: study-2022\n" in readme
    assert "![trajectory of local_prune](trajectories/pilotnet_local_prune_cpu1_montreal_cw.png)" in readme
    shapes = table_shapes(render_markdown(readme))
    assert [shape[0] for shape in shapes[:4]] == [9, 9, 7, 7] and len(shapes) == 4 + 4     # + trajectory tables
    assert all(len(set(shape)) == 1 for shape in shapes)     # n/a and failed rows keep the table's shape


def test_html_is_self_contained(study_report):
    data, paths = study_report
    page = paths.html.read_text()
    assert "Content-Security-Policy" in page and "default-src 'none'" in page
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", page)                # nothing from the network
    assert page.count("<img src=\"data:image/png;base64,") == 4 + 8
    links = re.findall(r'<a href="(trajectories/[^"]+\.png)" target="_blank"[^>]*><img src="data:', page)
    assert len(links) == 8 and all((paths.folder / link).is_file() for link in links)   # thumbnails open full size
    assert page.count("<table class=\"sortable") == 2 + 2 + 1
    assert "not applicable: static quantization kernels need 1 thread here" in page


def test_a_missing_baseline_a_single_row_and_no_online_part(tmp_path):
    rows = [offline_row("static_quant", size_mb=1.61, size_gz_mb=1.42, mse=0.07, latency_ms=1.2,
                        job_keys={"offline": "k1"})]
    paths = write_report(ReportData.from_dict(small_dict(rows)), tmp_path / "report")
    readme = paths.readme.read_text()
    assert "| static_quant | 1.61 | 1.42 | 0.0700 | 1.20 | — | — | — | — |" in readme
    assert read_csv(paths.csv)[0]["size_gz_mb"] == "1.42"
    assert "No usable 'baseline' row for pilotnet here: ratios are not shown." in readme
    assert "for the ratios: baseline (not among this report's strategies: no ratios)" in readme   # outside test
    assert "baseline (not among this report&#39;s strategies: no ratios)" in paths.html.read_text()
    assert "No closed-loop runs in this recipe." in readme
    assert set(paths.plots) == {"pareto"}                      # no baseline: no ratio bars; no laps, no history
    assert read_csv(paths.csv)[0]["job_offline"] == "k1"


def test_rewriting_a_report_removes_stale_plots_and_notes_missing_pictures(tmp_path):
    history = {"pilotnet": [{"epoch": 1, "train_loss": 0.2}, {"epoch": 2, "train_loss": 0.1}]}
    failed = offline_row(status="failed", reason="out of memory")
    first = write_report(ReportData.from_dict(small_dict([failed], histories=history)), tmp_path / "report")
    assert set(first.plots) == {"training"} and first.plots["training"][0].exists()
    lost = {"model": "pilotnet", "strategy": "baseline", "hardware": "cpu1", "kind": "online",
            "circuit": "montreal", "trajectory": str(tmp_path / "gone.png")}
    second = write_report(ReportData.from_dict(small_dict([failed, lost])), tmp_path / "report")
    assert second.plots == {} and not (tmp_path / "report/plots/training.png").exists()
    assert "baseline on cpu1, montreal: " in second.readme.read_text() and second.trajectories == {}
    assert "No plot: nothing was measured." in second.readme.read_text()


def test_recipe_text_cannot_inject_markup(tmp_path):
    evil = "<script>alert(1)</script>"
    rows = [offline_row("base|line", size_mb=1.0), offline_row(f"q{evil}", size_mb=0.5)]
    data = ReportData.from_dict(small_dict(rows, recipe_name=f"x{evil}", description=f"# {evil}\n\n*hi*",
                                           recipe_text=f"name: x{evil}\n```\n", baseline="base|line"))
    paths = write_report(data, tmp_path / "report")
    page, readme = paths.html.read_text(), paths.readme.read_text()
    assert evil not in readme.replace("name: x" + evil, "") and "x&lt;script&gt;alert(1)&lt;/script&gt;" in readme
    assert "| base\\|line | 1.00 |" in readme and "\\# &lt;script&gt;" in readme
    assert "````yaml\nname: x<script>alert(1)</script>\n```\n````" in readme      # verbatim inside the fence
    assert page.count("<script") == 1 and "x&lt;script&gt;alert(1)&lt;/script&gt;" in page
    rendered = render_markdown(readme)
    assert "<script" not in rendered and "<code class=\"language-yaml\">name: x&lt;script&gt;" in rendered
    assert "<h1>x&lt;script&gt;alert(1)&lt;/script&gt; — pilotlab report</h1>" in rendered
    assert all(len(set(shape)) == 1 for shape in table_shapes(rendered))


def test_a_recipe_with_no_cells_still_gets_a_report(tmp_path):
    paths = write_report(ReportData.from_dict(small_dict([])), tmp_path / "report")
    assert "No offline evaluation in this recipe." in paths.readme.read_text()
    assert "- **No results**: no cell produced a measurement" in paths.readme.read_text()
    assert read_csv(paths.csv) == [] and json.loads(paths.json.read_text())["rows"] == []


def test_the_same_data_gives_byte_identical_files(tmp_path):
    """So that a committed example report changes only where the results change."""
    rows = [offline_row("baseline", size_mb=6.1, mse=0.07, latency_ms=2.0), offline_row("qat", size_mb=1.6, mse=0.06)]
    data = ReportData.from_dict(small_dict(rows))
    first, second = write_report(data, tmp_path / "a"), write_report(data, tmp_path / "b")
    files = sorted(p.relative_to(first.folder) for p in first.folder.rglob("*") if p.is_file())
    assert len(files) == 4 + 2 * 2
    assert all((first.folder / f).read_bytes() == (second.folder / f).read_bytes() for f in files)


def test_repeated_laps_show_their_spread_in_both_pages_and_the_results_files(tmp_path):
    rows = repeated_rows()
    rows[1]["trajectory"] = str(draw_trajectory(tmp_path / "qat.png", wobble=1.0))
    paths = write_report(ReportData.from_dict(small_dict(rows)), tmp_path / "report")
    readme, page = paths.readme.read_text(), paths.html.read_text()
    assert "| baseline | ✓ 3/3, 47.8 ± 0.4 s | 8.95 ± 0.12 | 0.213 ± 0.0004 | — | — | — |" in readme
    assert "| qat | ✗ 2/3, 87 % | 8.41 ± 0.30 | 0.510 ± 0.000 | — | — | — |" in readme
    assert "| local_prune | ✓ 47.8 s | 8.95 | 0.213 | — | — | — |" in readme      # one run: as before
    assert "mean ± sample standard deviation over the runs" in readme and "mean ± sample standard" in page
    assert all(len(set(shape)) == 1 for shape in table_shapes(render_markdown(readme)))
    assert "| qat — 2 of 3 laps completed |" in readme                              # the picture's caption
    for text in ("✓ 3/3, 47.8 ± 0.4 s", "8.95 ± 0.12", "✗ 2/3, 87 %", "✓ 47.8 s"):
        assert f">{text}</td>" in page
    baseline, lost, single = read_csv(paths.csv)
    assert (baseline["repetitions"], baseline["repetitions_completed"]) == ("3", "3")
    assert lost["repetitions_completed"] == "2"
    assert (baseline["average_speed_std"], baseline["average_speed_min"], baseline["average_speed_max"]) == \
        ("0.123", "8.81", "9.05")
    assert (lost["lap_seconds_std"], single["repetitions"], single["average_speed_std"]) == ("0.2", "1", "")
    rows = json.loads(paths.json.read_text())["rows"]
    assert rows[0]["lap_seconds_std"] == 0.41 and rows[2]["lap_seconds_std"] is None     # missing, never 0
    assert list(rows[0]) == list(baseline)


def test_a_report_without_repeated_laps_has_no_spread_legend_or_columns(study_report):
    data, paths = study_report
    assert "standard deviation" not in paths.readme.read_text()
    assert not [name for name in read_csv(paths.csv)[0] if name.endswith("_std")]
    assert {row["repetitions"] for row in read_csv(paths.csv)} == {""}


def test_an_unstable_timing_is_marked_in_the_results_files_and_both_pages(tmp_path):
    reason = "only 4 of 24 calls (17 %) ran with no thread of this process waiting for a CPU"
    rows = [offline_row("baseline", latency_ms=2.3, latency_p10_ms=2.2, latency_p90_ms=9.5, threads=2,
                        latency_runs=24, unstable={"latency_ms": reason}),
            offline_row("static_quant", latency_ms=0.4, threads=2, latency_runs=900)]
    paths = write_report(ReportData.from_dict(small_dict(rows)), tmp_path)
    csv_rows = read_csv(paths.csv)
    assert [r["latency_ms_unstable"] for r in csv_rows] == [reason, ""] and csv_rows[0]["throughput_ips_unstable"] == ""
    assert {r["latency_ms_cpu_time"] for r in csv_rows} == {""}
    assert json.loads(paths.json.read_text())["rows"][0]["latency_ms_unstable"] == reason
    readme = paths.readme.read_text()
    assert "| baseline | — | — | — | 2.30 (2.20–9.50) ⚠ |" in readme
    assert f"⚠ baseline: inference time unstable: {reason}." in readme
    assert "Timings on 2 thread(s), one method at a time: inference time is the median of 24–900" in readme
    assert "**Fastest on cpu1**: not drawn: baseline (cpu1): unstable" in readme
    assert "; rerun `pilotlab run small.yaml --force timing` when the machine is quieter" in readme   # code, not \`
    assert "\\`" not in readme
    page = paths.html.read_text()
    assert "2.30 (2.20–9.50) ⚠" in page
    assert "; rerun <code>pilotlab run small.yaml --force timing</code> when the machine is quieter" in page and "`pilotlab" not in page


def test_a_lap_replaying_an_unstable_timing_is_marked_and_draws_no_verdict(tmp_path):
    """Outside test: a baseline timed at 132 ms under load (⚠ in the offline table) lost its replayed lap,
    and the simulation table, the closed-loop summary and results.csv said nothing of it."""
    reason = "it replays the timing of timing pilotnet/baseline on cpu1, which stayed disturbed (few calls)"
    lost = online_row("baseline", lap_completed=False, percentage_completed=12.0, brain_frequency_sim_hz=7.2,
                      mean_inference_ms=136.0)
    rows = [{**lost, "unstable": {"latency_ms": reason}},
            online_row("dynamic_quant", lap_completed=True, percentage_completed=100.0, lap_seconds=40.0,
                       mean_inference_ms=1.1)]
    paths = write_report(ReportData.from_dict(small_dict(rows)), tmp_path)
    assert [r["latency_ms_unstable"] for r in read_csv(paths.csv)] == [reason, ""]
    readme = paths.readme.read_text()
    assert "| baseline | ✗ 12 % ⚠ |" in readme and "| 136 ⚠ |" in readme
    assert f"⚠ baseline: no verdict from this lap: {reason}." in readme
    assert "lost the lap: baseline (12 %) ⚠ replaying an unstable timing" in readme


def test_each_summary_finding_is_a_line_of_its_own(study_report):
    """The template's line-ending tag once ate the newline: every finding ran into one line."""
    data, paths = study_report
    summary = paths.readme.read_text().split("## Summary", 1)[1].split("\n## ", 1)[0]
    findings = [line for line in summary.splitlines() if line.startswith("- **")]
    assert len(findings) >= 3 and all(line.count("- **") == 1 for line in findings)


def test_the_simulation_legend_explains_the_real_time_factor_and_the_behaviormetrics_columns(tmp_path):
    """Outside test: a lost lap's BM deviation (millions: 1000^d) and BM completed above 100 read as bugs
    where the markdown page said nothing about them (the HTML had them in tooltips only)."""
    with_bm = [online_row("baseline", lap_completed=True, bm_position_deviation_mae=1.32, bm_percentage_completed=102.0),
               online_row("qat", lap_completed=False, bm_position_deviation_mae=21_170_202.0, bm_percentage_completed=17.2)]
    paths = write_report(ReportData.from_dict(small_dict(with_bm)), tmp_path / "bm")
    for text in (paths.readme.read_text(), paths.html.read_text()):
        assert "Real-time factor: simulated seconds per wall-clock second" in text
        assert "reads in the millions" in text and "above 100 after a whole lap" in text
    plain = write_report(ReportData.from_dict(small_dict([online_row("baseline", lap_completed=True)])), tmp_path / "plain")
    readme = plain.readme.read_text()
    assert "Real-time factor: simulated seconds" in readme and "BM columns" not in readme


def test_a_training_on_too_little_data_is_said_beside_the_model(tmp_path):
    """Outside test: a network trained on 1 frame with no validation read "trained here", nothing else."""
    from pilotlab.report import ReportData
    from pilotlab.report.writer import write_report
    from tests.pilotlab.report.toy import offline_row, small_dict
    warning = "trained on 1 frame(s): too few to learn to drive from (under 200); record more, or longer laps"
    data = ReportData.from_dict({**small_dict([offline_row("baseline", mse=0.1)]),
                                 "training_warnings": {"pilotnet": [warning]}})
    write_report(data, tmp_path)
    assert f"- ⚠ **Model pilotnet** {warning}" in (tmp_path / "README.md").read_text()
    assert warning in (tmp_path / "index.html").read_text()
