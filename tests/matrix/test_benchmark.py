"""Engine speed: plan of a 10,000-job recipe, no-op rerun of a 1,000-job cached recipe.

Prints figures; never asserts timings (targets: plan < 2 s, no-op rerun < 1 s).
Run: python -m pytest -m benchmark -s tests/matrix/test_benchmark.py
"""
import subprocess
import sys
import time
from pathlib import Path

import pytest

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from tests.matrix.toydomain import TOY

ROOT = Path(__file__).resolve().parents[2]


def toy_recipe(path: Path, sources: int, powers: int) -> Path:
    lines = ["name: bench", "sources:"] + [f"  s{i}: {{value: {i}}}" for i in range(sources)]
    lines += ["matrix:", f"  source: [{', '.join(f's{i}' for i in range(sources))}]",
              f"  power: [{', '.join(str(p) for p in range(powers))}]"]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.benchmark
def test_plan_ten_thousand_jobs(tmp_path):
    recipe_path = toy_recipe(tmp_path / "r.yaml", 100, 99)   # 100 sources + 9,900 powers + 1 total
    started = time.perf_counter()
    recipe = load_recipe(recipe_path, TOY)
    plan = engine.make_plan(recipe, TOY, Store(tmp_path / "store"))
    seconds = time.perf_counter() - started
    print(f"\nplan of {len(plan.statuses)} jobs: {seconds:.2f} s (target < 2 s)")
    started = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "tests.matrix.toycli", "plan", str(recipe_path), "--json",
                          "--store", str(tmp_path / "store")], cwd=ROOT, capture_output=True, text=True)
    print(f"`plan --json` of {len(plan.statuses)} jobs from the command line, start-up included: "
          f"{time.perf_counter() - started:.2f} s")
    assert out.returncode == 0


@pytest.mark.benchmark
def test_noop_rerun_of_a_thousand_cached_jobs(tmp_path):
    recipe_path = toy_recipe(tmp_path / "r.yaml", 10, 99)     # 10 + 990 + 1 = 1,001 jobs
    store = Store(tmp_path / "store")
    recipe = load_recipe(recipe_path, TOY)
    started = time.perf_counter()
    summary = engine.run_plan(engine.make_plan(recipe, TOY, store), TOY, store, jobs=2)
    print(f"\ncold run of {len(summary.outcomes)} trivial jobs on 2 workers: {time.perf_counter() - started:.1f} s")
    started = time.perf_counter()
    plan = engine.make_plan(load_recipe(recipe_path, TOY), TOY, store)
    assert not plan.stale
    print(f"no-op rerun of {len(plan.statuses)} cached jobs (in process): "
          f"{time.perf_counter() - started:.2f} s (target < 1 s)")
    started = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "tests.matrix.toycli", "run", str(recipe_path),
                          "--store", str(store.root)], cwd=ROOT, capture_output=True, text=True)
    print(f"no-op `run` from the command line, interpreter start-up included: "
          f"{time.perf_counter() - started:.2f} s")
    assert "nothing to do" in out.stdout
