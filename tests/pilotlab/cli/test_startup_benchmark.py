"""How long `pilotlab plan recipes/study2022.yaml` takes from interpreter start to plan done (issue 26:
target < 0.5 s), in fresh interpreters after one warm-up run (bytecode written, the imports each source
file names remembered): prints the median wall and CPU seconds, how much of it is importing
pilotlab.cli and the planning modules, and the floor under both: a bare interpreter's start, and
pydantic's import with its first model validated (the recipe schema is pydantic; it loads
pydantic_core and, through its plugin loader, importlib.metadata). Never asserts a timing.
Run: python -m pytest -m benchmark -s tests/pilotlab/cli/test_startup_benchmark.py
"""
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.child import python_path

ROOT = Path(__file__).resolve().parents[3]
IMPORTS = ("import json, time; started = time.perf_counter(); import pilotlab.cli, pilotlab.domain; "
           "print(json.dumps(time.perf_counter() - started))")
PYDANTIC = ("import json, time; started = time.perf_counter(); import pydantic\n"
            "class First(pydantic.BaseModel):\n    x: int = 1\n"
            "First(x=2); print(json.dumps(time.perf_counter() - started))")
RUNS = 5


def child_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(argv: list[str], env: dict) -> tuple[float, float, str]:
    """(wall seconds, CPU seconds, stdout) of one fresh interpreter."""
    cpu, started = child_cpu(), time.perf_counter()
    out = subprocess.run([sys.executable, *argv], cwd=ROOT, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return time.perf_counter() - started, child_cpu() - cpu, out.stdout


@pytest.mark.benchmark
def test_plan_start_up(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env |= {"PYTHONPYCACHEPREFIX": str(tmp_path / "pycache"), "PYTHONPATH": python_path(ROOT)}
    plan = ["-c", "import sys; from pilotlab.cli import main; sys.exit(main(sys.argv[1:]))", "plan",
            "recipes/study2022.yaml", "--json", "--store", str(tmp_path / "store")]
    jobs = len(json.loads(timed(plan, env)[2]))     # the warm-up: bytecode and remembered imports written
    runs, imports, pydantic_s, floors, bares = [], [], [], [], []
    for _ in range(RUNS):      # in turn, so a change of the host's speed touches every figure alike
        runs.append(timed(plan, env))
        imports.append(json.loads(timed(["-c", IMPORTS], env)[2]))
        floor_wall, _, floor_out = timed(["-c", PYDANTIC], env)
        pydantic_s.append(json.loads(floor_out))
        floors.append(floor_wall)
        bares.append(timed(["-c", "pass"], env)[0])
    wall, cpu = statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)
    ratio = statistics.median(r[0] / f for r, f in zip(runs, floors))
    print(f"\n`pilotlab plan recipes/study2022.yaml --json` ({jobs} jobs), interpreter start to plan done, "
          f"median of {RUNS} fresh interpreters: {wall:.2f} s wall, {cpu:.2f} s CPU (target < 0.5 s; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores); of it importing pilotlab.cli "
          f"and pilotlab.domain: {statistics.median(imports):.2f} s; the floor: a bare interpreter "
          f"{statistics.median(bares):.2f} s, pydantic's import and first model {statistics.median(pydantic_s):.2f} s")
    print(f"the plan over a fresh interpreter importing pydantic with its first model (wall both, timed in turn): "
          f"{ratio:.2f}x; that floor's wall moved {max(floors) / min(floors):.2f}x across the rounds (this VM's "
          f"host changes speed under it: compare the ratio across runs, not the seconds)")
