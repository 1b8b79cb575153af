"""index.html in a real headless Chromium: no console errors, tables and plots on screen, sorting and
filters working, and recipe text that looks like markup never running.

Needs Debian's `chromium` (/usr/bin/chromium). Without it these tests skip, unless
PILOTLAB_REQUIRE_BROWSER=1 (as CI sets), where a missing browser is a failure.
Set PILOTLAB_SCREENSHOTS=folder to keep the screenshots.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest
from PIL import Image

from pilotlab.report import ReportData, write_report
from tests.pilotlab.report.chromium import CHROMIUM, FLAGS, open_page
from tests.pilotlab.report.toy import offline_row, online_rows, small_dict

MISSING = f"headless Chromium is not installed at {CHROMIUM} (apt-get install -y chromium)"
REQUIRED = os.environ.get("PILOTLAB_REQUIRE_BROWSER") == "1"
pytestmark = [pytest.mark.browser, pytest.mark.skipif(not CHROMIUM.exists() and not REQUIRED, reason=MISSING)]


@pytest.fixture(autouse=True)
def chromium_present():
    if not CHROMIUM.exists():                   # only reached when PILOTLAB_REQUIRE_BROWSER=1
        pytest.fail(MISSING + "; PILOTLAB_REQUIRE_BROWSER=1 requires it")


def keep(screenshot: Path) -> None:
    folder = os.environ.get("PILOTLAB_SCREENSHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        shutil.copy(screenshot, Path(folder) / screenshot.name)


def assert_shows_something(screenshot: Path, min_height: int) -> None:
    with Image.open(screenshot) as image:
        assert image.format == "PNG" and image.width >= 1000 and image.height >= min_height
        assert len(image.convert("RGB").getcolors(1 << 24)) > 200          # text, tables and plots, not a blank page


def test_page_opens_without_console_errors_and_shows_tables_and_plots(study_report, tmp_path):
    _, paths = study_report
    with open_page(paths.html.as_uri()) as page:
        assert page.problems() == []
        assert page.evaluate("document.querySelectorAll('section table tbody tr').length") >= 20
        plots = "[...document.querySelectorAll('#plots img')]"
        assert page.evaluate(plots + ".filter(i => i.complete && i.naturalWidth > 400).length") == 4
        assert page.evaluate("[...document.images].every(i => i.complete && i.naturalWidth > 0)")
        assert page.evaluate("document.querySelector('#offline table').getBoundingClientRect().height") > 200
        screenshot = page.screenshot(tmp_path / "report.png")
    keep(screenshot)
    assert_shows_something(screenshot, min_height=3000)


def test_columns_sort_with_missing_values_last(study_report):
    _, paths = study_report
    first_column = "[...document.querySelectorAll('#offline table')[1].tBodies[0].rows].map(r => r.cells[0].textContent)"
    with open_page(paths.html.as_uri()) as page:
        page.evaluate("document.querySelectorAll('#offline table')[1].tHead.rows[0].cells[4].click()")   # inference time
        assert page.evaluate(first_column) == ["local_prune", "global_prune", "baseline", "prune_quant",
                                               "dynamic_quant", "static_quant", "qat"]
        page.evaluate("document.querySelectorAll('#offline table')[1].tHead.rows[0].cells[4].click()")
        assert page.evaluate(first_column)[:2] == ["dynamic_quant", "prune_quant"]
        assert page.evaluate(first_column)[-2:] == ["static_quant", "qat"]            # n/a and failed stay last
        assert page.problems() == []


def test_filters_hide_other_rows_and_pictures(study_report):
    _, paths = study_report
    visible = "[...document.querySelectorAll('[data-filterable]')].filter(e => !e.hidden)"
    with open_page(paths.html.as_uri()) as page:
        page.evaluate("""(() => { const s = document.querySelector('select[data-filter=strategy]');
                          s.value = 'prune_quant'; s.dispatchEvent(new Event('change')); })()""")
        assert set(page.evaluate(visible + ".map(e => e.dataset.strategy)")) == {"prune_quant"}
        page.evaluate("""(() => { const s = document.querySelector('select[data-filter=circuit]');
                          s.value = 'montreal'; s.dispatchEvent(new Event('change')); })()""")
        pictures = page.evaluate("[...document.querySelectorAll('.gallery figure')].filter(e => !e.hidden).length")
        assert pictures == 1
        assert "rows and pictures shown" in page.evaluate("document.getElementById('filter-count').textContent")
        page.evaluate("document.getElementById('reset-filters').click()")
        assert page.evaluate(visible + ".length") == page.evaluate("document.querySelectorAll('[data-filterable]').length")
        assert page.problems() == []


def test_markup_in_recipe_text_does_not_execute(tmp_path):
    name = "<script>window.pwned = 1; console.error('pwned')</script>"
    rows = [offline_row("baseline", size_mb=6.1, mse=0.07, latency_ms=2.0),
            offline_row("<img src=x onerror=\"window.pwned=2\">", size_mb=1.6, mse=0.06, latency_ms=1.5),
            offline_row("qat", status="failed", reason="<svg onload=window.pwned=3>")]
    pictures = tmp_path / "pictures"
    pictures.mkdir()
    [lap] = online_rows(pictures, "montreal")[:1]
    rows.append({**lap, "circuit": "\"><script>window.pwned=4</script>"})
    data = ReportData.from_dict(small_dict(rows, recipe_name=name, recipe_text=name,
                                           description="<iframe src=javascript:window.pwned=5></iframe>"))
    paths = write_report(data, tmp_path / "report")
    with open_page(paths.html.as_uri()) as page:
        assert page.evaluate("typeof window.pwned") == "undefined"
        assert page.problems() == [] and "pwned" not in " ".join(page.console_messages())
        assert page.evaluate("document.getElementById('recipe-name').textContent") == name
        assert page.evaluate("document.scripts.length") == 1 and page.evaluate("document.images.length") >= 2
        assert page.evaluate("document.querySelectorAll('iframe, svg').length") == 0


def test_command_line_screenshot(study_report, tmp_path):
    """The plain `chromium --screenshot` path (what a person or CI script would run) renders the page."""
    _, paths = study_report
    screenshot = tmp_path / "cli.png"
    flags = [f for f in FLAGS if f != "--remote-debugging-pipe"]
    with tempfile.TemporaryDirectory(prefix="pilotlab-chromium-") as profile:
        subprocess.run([str(CHROMIUM), *flags, f"--user-data-dir={profile}", f"--screenshot={screenshot}",
                        "--window-size=1280,2400", paths.html.as_uri()],
                       check=True, timeout=60, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    keep(screenshot)
    assert_shows_something(screenshot, min_height=2400)
