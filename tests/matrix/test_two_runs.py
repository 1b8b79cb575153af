"""Two runs on one machine: in one folder at once both finish, no job runs twice, timing (exclusive)
jobs never overlap any other job of any run; after a kill, jobs that never ran are "new" and the
next run clears what the killed one left in tmp/ (not what a running job holds)."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from matrix import engine
from matrix.recipe import load_recipe
from matrix.stale import NOT_STORED
from matrix.store import Store
from tests.matrix.toydomain import TOY

ROOT = Path(__file__).resolve().parents[2]
RECIPE = """\
name: {name}
sources:
  a: {{value: 2, sleep: {sleep_a}}}
  {other}: {{value: {value}, sleep: {sleep_b}}}
sleep: 0.2
total_sleep: 0.5
matrix:
  source: [a, {other}]
  power: [2, 3]
"""


def write_recipe(folder: Path, name: str, other: str, sleep_a=0.3, sleep_b=0.3) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(RECIPE.format(name=name, other=other, value=len(other) + ord(other), sleep_a=sleep_a,
                                  sleep_b=sleep_b))
    return path


def start_run(recipe: Path, store: Path, jobs: int = 2) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tests.matrix.toycli", "run", str(recipe), "--store", str(store),
                             "-j", str(jobs)], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)


def intervals(store: Path) -> list[tuple[str, str, float, float]]:
    lines = (store / "cache" / "intervals.log").read_text().splitlines()
    return [(kind, key, float(start), float(end)) for kind, key, start, end, _ in map(str.split, lines)]


def keys_of(recipe: Path, store: Path) -> set[str]:
    return {s.job.key for s in engine.make_plan(load_recipe(recipe, TOY), TOY, Store(store)).statuses}


def test_concurrent_runs_share_the_work_and_timing_jobs_have_the_host_alone(tmp_path):
    one, two, store = write_recipe(tmp_path, "one", "b"), write_recipe(tmp_path, "two", "c"), tmp_path / "store"
    runs = [start_run(one, store), start_run(one, store), start_run(two, store)]
    for run in runs:
        out, err = run.communicate(timeout=120)
        assert run.returncode == 0, out + err
    ran = intervals(store)
    assert sorted(key for _, key, _, _ in ran) == sorted(keys_of(one, store) | keys_of(two, store))  # each once
    totals = [(start, end) for kind, _, start, end in ran if kind == "total"]
    assert len(totals) == 2
    for kind, key, start, end in ran:
        for total_start, total_end in totals:
            assert (start, end) == (total_start, total_end) or end <= total_start or start >= total_end, \
                f"{kind} {key[:8]} ran {start:.3f}-{end:.3f}, during a timing job {total_start:.3f}-{total_end:.3f}"


def test_after_a_kill_jobs_that_never_ran_are_new_and_the_next_run_clears_leftovers(tmp_path):
    recipe, store_root = write_recipe(tmp_path, "one", "b", sleep_a=0.0, sleep_b=60.0), tmp_path / "store"
    store = Store(store_root)
    statuses = engine.make_plan(load_recipe(recipe, TOY), TOY, store).statuses
    slow = next(s.job.key for s in statuses if s.job.name == "source b")
    run = start_run(recipe, store_root)
    deadline = time.monotonic() + 60
    while not any(p.name.startswith(slow[:16]) for p in (store_root / "tmp").glob("*")) \
            and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.3)
    os.killpg(run.pid, signal.SIGKILL)
    run.communicate(timeout=30)
    killed_leftover = next(p for p in (store_root / "tmp").iterdir() if p.name.startswith(slow[:16]))

    states = {s.job.name: (s.state, s.reason) for s in engine.make_plan(load_recipe(recipe, TOY), TOY, store).statuses}
    assert states["source a"] == ("fresh", "") and set(states.values()) <= {("fresh", ""), ("new", NOT_STORED)}
    assert {name: states[name] for name in ("source b", "power b^2", "power b^3", "total")} == dict.fromkeys(
        ("source b", "power b^2", "power b^3", "total"), ("new", NOT_STORED))

    held_key = "f" * 64                                       # a job another run is running right now
    in_flight = store_root / "tmp" / f"{held_key[:16]}-1-abcd"
    in_flight.mkdir()
    with store.lock(held_key) as held:
        assert held
        write_recipe(tmp_path, "one", "b", sleep_a=0.0, sleep_b=0.0)
        plan = engine.make_plan(load_recipe(recipe, TOY), TOY, store)
        assert engine.run_plan(plan, TOY, store).failed == []
    assert not killed_leftover.exists() and in_flight.exists()
