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
    assert {tuple(sorted(r)) for r in rows} == {("key", "kind", "name", "note", "reason", "status")}
    assert {r["status"] for r in rows} == {"new"} and {r["note"] for r in rows} == {""}


def test_plan_shows_what_a_kind_says_of_its_jobs(recipe, tmp_path, capsys):
    """note_kind: a few words beside a job in the plan, from its params (a lap's tolerance search); a note that
    trips on odd params is left out, never stopping the plan."""
    from matrix.kinds import KINDS, note_kind
    before = {name: KINDS.get(name) for name in ("power", "source")}
    try:
        note_kind("power", lambda params: f"to the power {params['power']}" if params["power"] > 1 else None)
        note_kind("source", lambda params: params["no such param"])
        code, out, _ = cli(capsys, "plan", str(recipe), "--json", "--store", str(tmp_path / "s"))
        notes = {row["kind"]: row["note"] for row in json.loads(out)}
        assert code == 0 and notes["power"] == "to the power 2" and notes["source"] == ""
        code, out, _ = cli(capsys, "plan", str(recipe), "--store", str(tmp_path / "s"))
        assert code == 0 and sum("to the power 2" in line for line in out.splitlines()) == 2
    finally:
        for name, kind in before.items():
            KINDS.replace(name, kind)


def test_a_plan_written_to_a_pipe_keeps_each_job_on_its_line(tmp_path, capsys, monkeypatch):
    """Outside test: `plan | less` fitted the table in 80 columns, job names cut or wrapped."""
    monkeypatch.delenv("COLUMNS", raising=False)
    long = "a_source_with_a_name_long_enough_to_need_more_than_eighty_columns"
    path = tmp_path / "r.yaml"
    path.write_text(RECIPE.replace("b: {value: %d}", f"{long}: {{value: 3}}").replace("[a, b]", f"[a, {long}]"))
    code, out, _ = cli(capsys, "plan", str(path), "--store", str(tmp_path / "s"))
    assert code == 0 and any(f"power {long}^2" in line for line in out.splitlines())


def test_plan_on_a_store_folder_that_is_not_there_says_so(recipe, tmp_path, capsys):
    """Outside test: `plan --store <typo>` showed every job "new" without a word (status refuses a typo)."""
    code, out, err = cli(capsys, "plan", str(recipe), "--store", str(tmp_path / "typo"))
    assert code == 0 and err == f"note: --store {tmp_path / 'typo'}: no such folder yet, so every job is new (`run` makes it)\n"
    assert not (tmp_path / "typo").exists()


def test_run_status_show_and_gc(recipe, tmp_path, capsys):
    store = str(tmp_path / "s")
    assert cli(capsys, "run", str(recipe), "--store", store)[0] == 0
    code, out, _ = cli(capsys, "status", "--store", store)
    assert code == 0 and "source" in out and "power" in out and "failed: 0 (a run of a recipe that reaches one reruns it" in out
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


def test_gc_names_a_failed_job_and_removes_its_work_folder_with_it(recipe, tmp_path, capsys):
    """Outside test: gc listed a failed job by its key alone, and its work folder (kept for its log) as a
    leftover of a killed run."""
    store = tmp_path / "s"
    recipe.write_text(RECIPE.replace("b: {value: %d}", "b: {value: 3, fail: true}"))
    assert cli(capsys, "run", str(recipe), "--store", str(store), "--keep-going")[0] == 1
    assert len(list((store / "tmp").iterdir())) == 1                 # the failed job's, kept for its log
    recipe.write_text(RECIPE % 4)
    code, out, _ = cli(capsys, "gc", str(recipe), "--dry-run", "--store", str(store))
    assert " source b (failed)\n" in out and "and 0 leftovers of killed runs" in out
    cli(capsys, "gc", str(recipe), "--store", str(store))
    assert list((store / "tmp").iterdir()) == [] and list((store / "failed").iterdir()) == []


def test_gc_keeps_what_the_domain_keeps_for_another_host_unless_all_hosts(recipe, tmp_path, capsys):
    import dataclasses
    domain = dataclasses.replace(TOY, kept_elsewhere=lambda spec: "planned elsewhere" if spec.get("name") == "source b"
                                 else None)
    store = str(tmp_path / "s")
    assert main(["run", str(recipe), "--store", store], domain) == 0
    recipe.write_text(RECIPE % 4)
    assert main(["run", str(recipe), "--store", store], domain) == 0
    capsys.readouterr()
    assert main(["gc", str(recipe), "--dry-run", "--store", store], domain) == 0
    out = capsys.readouterr().out
    assert "would remove 2 jobs" in out   # the old power b^2 and total; the old source b is kept for elsewhere
    assert "keeping 1 stored jobs no recipe reaches here: planned elsewhere (gc there collects them, or gc " \
           "--all-hosts here)" in out
    assert main(["gc", str(recipe), "--all-hosts", "--store", store], domain) == 0
    assert "removed 3 jobs" in capsys.readouterr().out


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


def test_a_large_plan_is_summarised_per_kind_and_all_of_it_is_in_json(tmp_path, capsys):
    from matrix.display import PLAN_ROWS
    path = tmp_path / "big.yaml"
    path.write_text("name: big\nsources:\n  a: {value: 2}\nmatrix:\n  source: [a]\n"
                    f"  power: [{', '.join(str(p) for p in range(2 * PLAN_ROWS))}]\n")
    store = str(tmp_path / "s")
    code, out, _ = cli(capsys, "plan", str(path), "--store", store)
    total = 2 * PLAN_ROWS + 2   # one source, the powers, one total
    assert code == 0 and f"the first {PLAN_ROWS} of {total} jobs" in out and "toy plan --all" in out
    assert sum(line.startswith("new ") for line in out.splitlines()) == PLAN_ROWS
    kinds = {line.split()[0]: line.split()[1:] for line in out.splitlines()[1:4]}
    assert kinds == {"source": ["·", "·", "1", "1"], "power": ["·", "·", str(2 * PLAN_ROWS), str(2 * PLAN_ROWS)],
                     "total": ["·", "·", "1", "1"]}
    assert sum(line.startswith("new ") for line in cli(capsys, "plan", str(path), "--store", store, "--all")[1].splitlines()) \
        == total
    assert len(json.loads(cli(capsys, "plan", str(path), "--store", store, "--json")[1])) == total


def test_status_times_sums_job_durations_per_kind(recipe, tmp_path, capsys):
    store = str(tmp_path / "s")
    (tmp_path / "slow.yaml").write_text((RECIPE % 3).replace("b: {value: 3}", "b: {value: 3, sleep: 0.5}"))
    assert cli(capsys, "run", str(tmp_path / "slow.yaml"), "--store", store)[0] == 0
    code, out, _ = cli(capsys, "status", "--store", store, "--times", "--recipe", "toy")
    lines = out.splitlines()
    assert code == 0 and lines[1].split()[:2] == ["source", "2"]   # the slowest kind first
    assert float(lines[1].split()[2]) >= 0.5 and "source b" in lines[1]
    assert "recipe toy: 5 jobs" in out
    assert cli(capsys, "status", "--store", store, "--times", "--recipe", str(tmp_path / "slow.yaml"))[1] == out
    assert cli(capsys, "status", "--store", store, "--times", "--recipe", "nope")[0] == 2
    # as `run` and `plan` take it (`status recipes/study.yaml` was an argparse error)
    assert cli(capsys, "status", "--store", store, str(tmp_path / "slow.yaml"))[1] == out
    code, _, err = cli(capsys, "status", "--store", store, "toy", "--recipe", "other")
    assert code == 2 and "two recipes given" in err


def test_engine_commands_are_the_ones_named_for_command_lines_that_load_commands_lazily():
    import argparse
    from matrix.cli import ENGINE_COMMANDS, add_engine_commands
    subparsers = argparse.ArgumentParser().add_subparsers()
    add_engine_commands(subparsers, lambda: TOY)
    assert tuple(subparsers.choices) == ENGINE_COMMANDS


def test_gc_waits_for_the_runs_on_its_store_and_removes_only_jobs(recipe, tmp_path, capsys):
    """Outside test: gc of another recipe, while a run was running on the store, removed the jobs that
    run had just finished, and the run failed reading them. Now gc is refused while a run holds the
    store (`Store.running`), and after it the jobs are there; a folder or file put under jobs/ by hand
    is not a job: gc neither lists it as removed nor touches it."""
    from matrix.store import Store
    store = Store(tmp_path / "s")
    assert cli(capsys, "run", str(recipe), "--store", str(store.root))[0] == 0
    other = tmp_path / "other.yaml"
    other.write_text(RECIPE.replace("name: toy", "name: other") % 7)
    with store.running():                                # a run of the recipe is going on
        code, out, err = cli(capsys, "gc", str(other), "--store", str(store.root))
        assert code == 2 and "a run is running on the store" in err and "when it has ended" in err
    assert len(list(store.keys())) == 5
    foreign = store.root / "jobs" / "zz" / "notakey"
    foreign.mkdir(parents=True)
    (store.root / "jobs" / "README.md").write_text("mine\n")
    code, out, _ = cli(capsys, "gc", str(other), "--store", str(store.root))
    assert code == 0 and "removed 3 jobs" in out and "notakey" not in out and "README" not in out
    assert foreign.is_dir() and len(list(store.keys())) == 2          # source a: both recipes have it


def test_status_of_a_store_that_is_not_there_says_so(tmp_path, capsys, monkeypatch):
    """Outside test: `status --store /nonexistent` said "no finished jobs yet", as of an empty store."""
    code, out, err = cli(capsys, "status", "--store", str(tmp_path / "nosuch"))
    assert code == 2 and "no such folder" in err and not (tmp_path / "nosuch").exists()
    monkeypatch.chdir(tmp_path)
    code, out, err = cli(capsys, "status")
    assert code == 0 and "yet: `run RECIPE` makes it" in out


@pytest.mark.parametrize("command", ["plan", "run", "status"])
def test_a_store_that_is_a_file_is_said_to_be_one(recipe, tmp_path, capsys, command):
    """outside test: `plan --store r.yaml` said 'no such folder yet, every job is new', `run` then failed
    on 'locks: Not a directory' and `status` said 'no such folder'."""
    args = [command, str(recipe)] if command != "status" else [command]
    code, out, err = cli(capsys, *args, "--store", str(recipe))
    assert code == 2 and f"--store {recipe}: a file, not a store folder; give a folder" in err
    assert err.count("\n") == 1 and recipe.read_text() == RECIPE % 3


def test_a_run_with_nothing_to_do_is_the_recipe_s_last_run_and_clears_killed_runs_leftovers(recipe, tmp_path, capsys):
    """outside test: a run that found every job fresh was not recorded (`status --recipe` of the recipe just
    run said it never ran; plan's reasons compared with an older run) and left killed runs' tmp/ folders."""
    store = tmp_path / "s"
    assert cli(capsys, "run", str(recipe), "--store", str(store))[0] == 0
    renamed = tmp_path / "renamed.yaml"
    renamed.write_text(recipe.read_text().replace("name: toy", "name: renamed"))
    leftover = store / "tmp" / "0123456789abcdef-99999-killed"
    leftover.mkdir(parents=True)
    code, out, _ = cli(capsys, "run", str(renamed), "--store", str(store))
    assert code == 0 and "nothing to do" in out and not leftover.exists()
    code, out, _ = cli(capsys, "status", "--store", str(store), "--times", "--recipe", "renamed")
    assert code == 0 and "recipe renamed: 5 jobs" in out


def test_status_counts_running_jobs_not_the_run_itself(recipe, tmp_path, capsys):
    """outside test: during a -j 1 run `status` said 'running now: 2': the store's runs.lock counted as a job."""
    from matrix.store import Store
    store = Store(tmp_path / "s")
    assert cli(capsys, "run", str(recipe), "--store", str(store.root))[0] == 0
    with store.running(), store.lock(next(iter(store.keys()))):
        code, out, _ = cli(capsys, "status", "--store", str(store.root))
    assert code == 0 and "running now: 1" in out


def test_gc_names_a_recipe_that_ran_here_and_loses_jobs_and_status_says_what_is_gone(recipe, tmp_path, capsys):
    """Outside test: gc given one recipe removed another's jobs without a word, and `status` went on showing
    that recipe's job count as if they were stored."""
    store = str(tmp_path / "s")
    other = tmp_path / "other.yaml"
    other.write_text(RECIPE.replace("name: toy", "name: other").replace("b: {value: %d}", "b: {value: 7}"))
    assert cli(capsys, "run", str(other), "--store", store)[0] == 0
    assert cli(capsys, "run", str(recipe), "--store", store)[0] == 0
    code, out, _ = cli(capsys, "gc", str(recipe), "--dry-run", "--store", store)
    assert f"recipe other ({other}), which ran on this store and was not given, would lose 3 of its 5 jobs: give " \
           "its file too to keep them" in out
    code, out, _ = cli(capsys, "gc", str(recipe), "--store", store)
    assert "recipe other" in out and "lost 3 of its 5 jobs" in out
    assert "lost" not in cli(capsys, "gc", str(recipe), str(other), "--dry-run", "--store", store)[1]
    out = cli(capsys, "status", "--store", store)[1]
    assert f"recipe other: 5 jobs ({other}), 3 of them not stored now" in out
    assert f"recipe toy: 5 jobs ({recipe})\n" in out


def test_status_names_the_failed_jobs_and_forgets_a_failure_once_a_run_keeps_the_result(recipe, tmp_path, capsys):
    """Outside test: `status` said "failed: 1" (which?) and went on saying it after a run had kept the
    job's result."""
    store = tmp_path / "s"
    assert cli(capsys, "run", str(recipe), "--store", str(store))[0] == 0
    key = json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", str(store))[1])[-1]["key"]
    (store / "failed").mkdir(exist_ok=True)
    (store / "failed" / f"{key}.json").write_text(json.dumps({"error": "boom", "spec": {"name": "total"}}))
    assert "failed: 1: total (a run" in cli(capsys, "status", "--store", str(store))[1]
    assert cli(capsys, "run", str(recipe), "--store", str(store), "--force", "source")[0] == 0   # total: kept
    assert "failed: 0 (a run" in cli(capsys, "status", "--store", str(store))[1]


def test_a_job_removed_from_the_store_since_it_ran_is_not_just_new(recipe, tmp_path, capsys):
    """Outside test: a job deleted by hand (or by gc) was planned as "new", as if never seen."""
    import shutil
    store = tmp_path / "s"
    assert cli(capsys, "run", str(recipe), "--store", str(store))[0] == 0
    total = json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", str(store))[1])[-1]
    shutil.rmtree(next((store / "jobs").glob(f"*/{total['key']}")))
    row = json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", str(store))[1])[-1]
    assert (row["status"], row["reason"]) == ("new", "not in the store: the last run did not finish it, or it was "
                                                     "removed since (gc, or by hand)")


def test_show_says_a_stored_result_is_corrupt(recipe, tmp_path, capsys):
    """Outside test: `show` on a job whose result.json was truncated printed its settings alone."""
    store = tmp_path / "s"
    assert cli(capsys, "run", str(recipe), "--store", str(store))[0] == 0
    total = json.loads(cli(capsys, "plan", str(recipe), "--json", "--store", str(store))[1])[-1]
    next((store / "jobs").glob(f"*/{total['key']}/result.json")).write_text('{"stat')
    code, out, _ = cli(capsys, "show", total["key"][:10], "--store", str(store))
    assert code == 0 and "status: stored result missing or corrupt" in out
