"""The engine's commands through the toy domain's command line: plan --json, status, show, gc."""
import json

import pytest

from matrix.cli import main
from tests.matrix.toydomain import TOY

RECIPE = """\
name: toy
sources:
  a: {value: 2}
  b: {value: %d}
matrix:
  source: [a, b]
  power: [2]
"""


@pytest.fixture
def recipe(tmp_path):
    path = tmp_path / "r.yaml"
    path.write_text(RECIPE % 3)
    return path


def cli(capsys, *args) -> tuple[int, str, str]:
    code = main(list(args), TOY, prog="toy")
    out, err = capsys.readouterr()
    return code, out, err


def test_plan_json_lists_key_kind_status_reason(recipe, tmp_path, capsys):
    code, out, _ = cli(capsys, "plan", str(recipe), "--json", "--store", str(tmp_path / "s"))
    rows = json.loads(out)
    assert code == 0 and len(rows) == 5
    assert {tuple(sorted(r)) for r in rows} == {("key", "kind", "name", "reason", "status")}
    assert {r["status"] for r in rows} == {"new"}


def test_run_status_show_and_gc(recipe, tmp_path, capsys):
    store = str(tmp_path / "s")
    assert cli(capsys, "run", str(recipe), "--store", store)[0] == 0
    code, out, _ = cli(capsys, "status", "--store", store)
    assert code == 0 and "source" in out and "power" in out and "failed (will rerun): 0" in out
    key = json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", store)[1])[-1]["key"]
    code, out, _ = cli(capsys, "show", key[:8], "--store", store)
    assert code == 0 and "total" in out and "status: ok" in out and "log.txt" in out
    recipe.write_text(RECIPE % 4)
    assert cli(capsys, "run", str(recipe), "--store", store)[0] == 0
    code, out, _ = cli(capsys, "gc", str(recipe), "--dry-run", "--store", store)
    assert "would remove 3 jobs" in out and "keeping the 5 stored jobs" in out   # 8 stored: 3 old, 2 shared, 3 new
    code, out, _ = cli(capsys, "gc", str(recipe), "--store", store)
    assert "removed 3 jobs" in out
    assert cli(capsys, "gc", str(recipe), "--store", store)[1].startswith("removed 0 jobs")


def test_a_failed_run_exits_non_zero_and_show_explains(recipe, tmp_path, capsys):
    recipe.write_text(RECIPE.replace("{value: %d}", "{value: 1, fail: true}"))
    store = str(tmp_path / "s")
    code, out, err = cli(capsys, "run", str(recipe), "--store", store, "--keep-going")
    assert code == 1 and "failed" in out
    key = next(r["key"] for r in json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", store)[1])
               if r["name"] == "source b")
    assert f"toy show {key[:10]}   # source b" in out                    # the run names the key to look at
    code, out, _ = cli(capsys, "show", key, "--store", store)
    assert "failed last time" in out and "was told to fail" in out


def test_unknown_key_prefix(recipe, tmp_path, capsys):
    code, _, err = cli(capsys, "show", "abcdef", "--store", str(tmp_path / "s"))
    assert code == 2 and "no job 'abcdef'" in err


@pytest.mark.parametrize("key", ["../../x_marker", "[a-f]*", "/etc/passwd", "ab*", "abcd/../..", "g" * 8,
                                 "a" * 65])
def test_a_key_is_hex_digits_never_a_path_or_pattern(recipe, tmp_path, capsys, key):
    store = tmp_path / "s"
    cli(capsys, "run", str(recipe), "--store", str(store))
    (tmp_path / "x_marker.json").write_text("{}")                     # what `../../x` once matched
    code, out, err = cli(capsys, "show", key, "--store", str(store))
    assert code == 2 and "is not a job key" in err and len(err.strip().splitlines()) == 1 and out == ""


def test_a_key_prefix_in_capitals_is_found(recipe, tmp_path, capsys):
    store = str(tmp_path / "s")
    cli(capsys, "run", str(recipe), "--store", store)
    key = json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", store)[1])[0]["key"]
    assert cli(capsys, "show", key[:8].upper(), "--store", store)[0] == 0
