"""Killed runs and concurrent runs on one store, through the real command line."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from matrix.store import Store
from tests.child import python_path

ROOT = Path(__file__).resolve().parents[2]
SLOW_RECIPE = """\
name: slow
sleep: 0.4
sources:
  a: {value: 1}
  b: {value: 2}
  c: {value: 3}
matrix:
  source: [a, b, c]
  power: [1, 2, 3]
"""


def toy(*args, **popen):
    env = dict(os.environ, PYTHONPATH=python_path(ROOT))
    return subprocess.Popen([sys.executable, "-m", "tests.matrix.toycli", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, **popen)


def plan_states(recipe, store):
    out, err = toy("plan", str(recipe), "--store", str(store), "--json").communicate(timeout=60)
    return {row["name"]: row["status"] for row in json.loads(out)}


def test_sigkill_loses_only_jobs_in_flight(tmp_path):
    recipe, store = tmp_path / "r.yaml", tmp_path / "store"
    recipe.write_text(SLOW_RECIPE)
    process = toy("run", str(recipe), "--store", str(store))
    deadline = time.time() + 60
    while time.time() < deadline and len(list(Store(store).keys())) < 4:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)  # the driver and its workers, mid-run
    process.wait()
    done_before = set(Store(store).keys())
    assert 4 <= len(done_before) < 13
    for key in done_before:  # every stored entry is whole
        assert Store(store).result(key)["status"] == "ok"
    states = plan_states(recipe, store)
    assert list(states.values()).count("fresh") == len(done_before)
    out, err = toy("run", str(recipe), "--store", str(store)).communicate(timeout=120)
    assert "done: " in out, err
    assert set(plan_states(recipe, store).values()) == {"fresh"}


def test_two_runs_together_run_every_job_exactly_once(tmp_path):
    recipe, store = tmp_path / "r.yaml", tmp_path / "store"
    recipe.write_text(SLOW_RECIPE)
    runs = [toy("run", str(recipe), "--store", str(store), "-j", "2") for _ in range(2)]
    outputs = [run.communicate(timeout=180) for run in runs]
    assert [run.returncode for run in runs] == [0, 0], outputs
    executions = (store / "cache" / "executions.log").read_text().splitlines()
    assert len(executions) == 13 and len(set(executions)) == 13
    assert set(plan_states(recipe, store).values()) == {"fresh"}


def test_cli_errors_are_one_line_without_traceback(tmp_path):
    recipe = tmp_path / "r.yaml"
    recipe.write_text(SLOW_RECIPE.replace("power: [1, 2, 3]", "powr: [1]"))
    process = toy("plan", str(recipe), "--store", str(tmp_path / "s"))
    out, err = process.communicate(timeout=60)
    assert process.returncode == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"toy: error: {recipe}:9: matrix.powr: unknown axis 'powr' (did you mean 'power'?)")


def test_workers_die_with_a_killed_run(tmp_path):
    """The run killed alone (not its process group): its workers stop instead of running on as orphans."""
    process, workers, store = run_with_two_workers(tmp_path)
    assert len(workers) >= 2
    process.kill()                      # SIGKILL to the driver only
    process.wait()
    deadline = time.time() + 20
    while time.time() < deadline and any(alive(pid) for pid in workers):
        time.sleep(0.1)
    assert not any(alive(pid) for pid in workers)


def run_with_two_workers(tmp_path):
    """A run of 30 s jobs on two workers, once both are up: (process, worker pids, store folder)."""
    recipe, store = tmp_path / "r.yaml", tmp_path / "store"
    recipe.write_text(SLOW_RECIPE.replace("sleep: 0.4", "sleep: 30"))
    process = toy("run", str(recipe), "--store", str(store), "-j", "2")
    workers = []
    deadline = time.time() + 60
    while time.time() < deadline and len(workers) < 2:
        workers = children(process.pid)
        time.sleep(0.1)
    return process, workers, store


def children(pid: int) -> list[int]:
    """The worker processes of `pid` (multiprocessing's spawned children, not its resource tracker)."""
    found = []
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            text = status.read_text()
            cmdline = (status.parent / "cmdline").read_bytes()
        except OSError:
            continue
        if f"\nPPid:\t{pid}\n" in text and b"spawn_main" in cmdline:
            found.append(int(status.parent.name))
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_an_interrupt_the_driver_alone_gets_stops_the_running_jobs(tmp_path):
    """Outside test: `kill -INT PID` (the driver only; a terminal's Ctrl-C reaches every process of the
    group) was ignored until the running job had ended, 20 s later, with no word. The driver now passes
    the interrupt on to its workers."""
    process, workers, store = run_with_two_workers(tmp_path)
    time.sleep(1.0)                        # the jobs have started their 30 s
    started = time.time()
    os.kill(process.pid, signal.SIGINT)
    process.communicate(timeout=25)
    assert time.time() - started < 10 and process.returncode != 0
    assert not any(alive(pid) for pid in workers)
    stored = list(Store(store).keys())             # the sources (no sleep) done; no 30 s job stored half done
    assert len(stored) < 13 and all(Store(store).result(key)["status"] == "ok" for key in stored)


def test_sigterm_stops_the_run_as_an_interrupt_does(tmp_path):
    """Outside test: `kill PID` (SIGTERM, as `timeout` and batch systems send it) ended the run at once with
    multiprocessing's "leaked semaphore objects" warning and no word of ours. It now stops as at Ctrl-C:
    the running jobs interrupted, nothing half-written, Terminated raised (the CLI says so, exit 143)."""
    process, workers, store = run_with_two_workers(tmp_path)
    time.sleep(1.0)
    started = time.time()
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=25)
    assert time.time() - started < 10 and process.returncode != 0
    assert "Terminated" in err and "leaked semaphore" not in err, err
    assert not any(alive(pid) for pid in workers)
    stored = list(Store(store).keys())
    assert len(stored) < 13 and all(Store(store).result(key)["status"] == "ok" for key in stored)


def test_ctrl_c_with_an_idle_worker_prints_no_traceback(tmp_path):
    """Outside test: Ctrl-C (the whole process group, as a terminal sends it) while one worker was idle
    printed a 20-line traceback from that worker's queue wait before "interrupted". An idle worker ignores
    it now; the busy one's job is interrupted as before."""
    recipe, store = tmp_path / "r.yaml", tmp_path / "store"
    recipe.write_text("name: idle\nsleep: 0\nsources:\n  a: {value: 1, sleep: 30}\n  b: {value: 2}\n"
                      "matrix:\n  source: [a, b]\n  power: [1]\n")
    process = toy("run", str(recipe), "--store", str(store), "-j", "2")
    deadline = time.time() + 60
    while time.time() < deadline and len(list(Store(store).keys())) < 2:   # source b and power b^1 done
        time.sleep(0.1)
    time.sleep(0.5)
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=30)
    assert process.returncode != 0 and "KeyboardInterrupt" in err          # the driver's (the toy CLI has no handler)
    assert "Process SpawnProcess" not in err and "call_queue.get" not in err, err   # no worker's
