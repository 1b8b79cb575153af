"""The same DAG on a Dask LocalCluster sharing the job store."""
import os
import signal
import threading
import time

import pytest

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from matrix.worker import HOST_BUSY, RUNNING
from tests.matrix.toydomain import TOY

distributed = pytest.importorskip("distributed")

RECIPE = """\
name: toy
sources:
  a: {value: 2}
  b: {value: 3, sleep: %s}
  c: {value: 5}
matrix:
  source: [a, b, c]
  power: [2, 3]
"""


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    with distributed.Client(cluster) as client:
        yield client
    cluster.close()


def results(store: Store, plan) -> dict:
    return {s.job.key: store.result(s.job.key)["value"] for s in plan.statuses}


def plan_of(tmp_path, store, sleep="0.1"):
    path = tmp_path / "r.yaml"
    path.write_text(RECIPE % sleep)
    return engine.make_plan(load_recipe(path, TOY), TOY, store)


def test_dask_gives_the_same_keys_and_results_as_the_local_executor(tmp_path, client):
    from matrix.dask_executor import run_dask
    local, remote = Store(tmp_path / "local"), Store(tmp_path / "dask")
    engine.run_plan(plan_of(tmp_path, local), TOY, local, jobs=2)
    plan = plan_of(tmp_path, remote)
    summary = run_dask(plan.statuses, remote, client, kind_modules=TOY.kind_modules)
    assert summary.counts() == {"ok": 10}
    assert results(local, plan) == results(remote, plan)
    assert sorted(local.keys()) == sorted(remote.keys())
    # The store is the source of truth: the local executor finds every job fresh.
    assert not plan_of(tmp_path, remote).stale


class Recorded:
    """A display that notes what it is told."""

    def __init__(self):
        self.started, self.progress, self.finished = [], [], []

    def job_started(self, job):
        self.started.append(job.name)

    def job_waiting(self, job):
        pass

    def job_progress(self, key, **update):
        self.progress.append((key, update))

    def job_finished(self, outcome):
        self.finished.append(outcome.name)


def test_the_display_learns_which_jobs_run_on_dask_and_their_progress(tmp_path, client):
    """Outside test: under Dask the progress line named no running job (the local pool's display is told
    when each starts, and its progress); the tasks now send both to the driver as Dask events."""
    from matrix.dask_executor import run_dask
    store = Store(tmp_path / "s")
    plan = plan_of(tmp_path, store, sleep="0.3")
    display = Recorded()
    run_dask(plan.statuses, store, client, kind_modules=TOY.kind_modules, display=display)
    assert sorted(display.finished) == sorted(s.job.name for s in plan.statuses)
    # a job's start is told 0.3 s before its result; its last progress update races the result (and is
    # dropped when it loses: the job is no longer shown)
    assert {"source a", "source b", "source c", "total"} <= set(display.started)
    # a job that found the host taken (by another run's timing job) says it waits, then that it runs;
    # otherwise only the sources report progress
    sources = {s.job.key for s in plan.statuses if s.job.kind == "source"}
    keys = {s.job.key for s in plan.statuses}
    told = [(key, update["description"]) for key, update in display.progress
            if update["description"] not in (HOST_BUSY, RUNNING)]
    assert all(key in sources and description == "written" for key, description in told)
    assert all(key in keys for key, _ in display.progress)


def test_a_failure_on_dask_skips_dependents(tmp_path, client):
    from matrix.dask_executor import run_dask
    path = tmp_path / "r.yaml"
    path.write_text((RECIPE % "0").replace("{value: 5}", "{value: 5, fail: true}"))
    store = Store(tmp_path / "s")
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    summary = run_dask(plan.statuses, store, client, keep_going=True, kind_modules=TOY.kind_modules)
    status = {o.name: o.status for o in summary.outcomes}
    assert status["source c"] == "failed" and status["power c^2"] == "skipped" and status["total"] == "skipped"
    assert status["power a^3"] == "ok"


def test_a_job_no_worker_can_take_is_not_started_saying_which_resource(tmp_path, client):
    """Outside test: a profile's timing jobs needing a resource no worker declared waited for ever, the
    run showing "about 0:00:04 left"; now they are not started, saying which resource and how to add it,
    the jobs standing on them are skipped and the rest runs."""
    from matrix.dask_executor import run_dask
    path = tmp_path / "r.yaml"
    path.write_text((RECIPE % "0").replace("{value: 2}", "{value: 2, worker: ON_A}") + "measures: true\n")
    store = Store(tmp_path / "s")
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    summary = run_dask(plan.statuses, store, client, kind_modules=TOY.kind_modules)
    outcomes = {o.name: o for o in summary.outcomes}
    assert outcomes["measure power a^2"].status == "not_started"
    assert "no worker of the Dask cluster declares the resource 'ON_A'" in outcomes["measure power a^2"].reason
    assert '--resources "ON_A=1"' in outcomes["measure power a^2"].reason
    assert outcomes["measure power b^2"].status == outcomes["total"].status == "ok"
    assert summary.failed and len(summary.outcomes) == len(plan.statuses)


def page_faults_of_reused_allocations() -> tuple[bool, float]:
    """On a worker: whether the nanny set MALLOC_TRIM_THRESHOLD_, and the page faults of a 1 MiB buffer
    allocated, touched and freed again and again, once a task has run there (matrix.dask_executor)."""
    import resource
    import numpy as np
    from matrix.dask_executor import _malloc_as_a_plain_process
    _malloc_as_a_plain_process()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(200):
        np.ones(1 << 17)          # 1 MiB, touched
    return "MALLOC_TRIM_THRESHOLD_" in os.environ, (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 200


def test_a_dask_worker_allocates_as_a_plain_process(client):
    """Outside test: torch's eager PilotNet timed 2-4x slower on Dask workers: the nanny's
    MALLOC_TRIM_THRESHOLD_ turns glibc's dynamic mmap threshold off, so every buffer above 128 KiB was a
    fresh mmap (256 page faults a MiB). A worker running our task reuses its heap as a plain process."""
    nanny_set_it, faults = client.submit(page_faults_of_reused_allocations, pure=False).result()
    assert nanny_set_it and faults < 20


def test_a_worker_killed_mid_job_is_survived(tmp_path, client):
    from matrix.dask_executor import run_dask
    store = Store(tmp_path / "s")
    plan = plan_of(tmp_path, store, sleep="4")
    slow = next(s.job for s in plan.statuses if s.job.name == "source b")
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.update(
        summary=run_dask(plan.statuses, store, client, kind_modules=TOY.kind_modules)))
    thread.start()
    victim = None
    deadline = time.time() + 30
    while victim is None and time.time() < deadline:
        for worker, keys in client.processing().items():
            if any(key.endswith(slow.key) for key in keys):
                victim = worker
        time.sleep(0.1)
    assert victim, "the slow job never started"
    time.sleep(1.0)  # well inside the job
    pid = client.run(os.getpid, workers=[victim])[victim]
    os.kill(pid, signal.SIGKILL)
    thread.join(timeout=120)
    summary = outcome["summary"]
    assert {o.status for o in summary.outcomes} <= {"ok", "done_elsewhere"}, summary.outcomes
    for s in plan.statuses:  # no half-written entry: every job has a whole result
        assert store.result(s.job.key)["status"] == "ok"
        assert store.outputs_intact(s.job.key, store.result(s.job.key))
    assert not plan_of(tmp_path, store, sleep="4").stale
    executions = (store.root / "cache" / "executions.log").read_text().splitlines()
    assert executions.count("source b") == 2  # killed once, then run again elsewhere


def test_a_task_of_another_run_with_the_same_job_key_is_not_reused(tmp_path, client):
    """Dask reuses a task whose key it still holds; a job key names the job, not the run or the
    store, so a run must not hand its jobs to Dask under the bare job key (a held task of an earlier
    run on another store would stand in for the job, and its dependents find no result here)."""
    from matrix.dask_executor import run_dask
    store = Store(tmp_path / "s")
    plan = plan_of(tmp_path, store)
    source_a = next(s.job for s in plan.statuses if s.job.name == "source a")
    held = client.submit(lambda: {"status": "ok", "name": "source a"}, key=source_a.key, pure=False)
    held.result()
    summary = run_dask(plan.statuses, store, client, kind_modules=TOY.kind_modules)
    assert summary.counts() == {"ok": 10}, summary.outcomes
    assert all(store.result(s.job.key) for s in plan.statuses)


def test_force_reruns_on_dask(tmp_path, client):
    from matrix.dask_executor import run_dask
    store = Store(tmp_path / "s")
    run_dask(plan_of(tmp_path, store).statuses, store, client, kind_modules=TOY.kind_modules)
    path = tmp_path / "r.yaml"
    forced = engine.make_plan(load_recipe(path, TOY), TOY, store, ["power"])
    summary = run_dask(forced.statuses, store, client, kind_modules=TOY.kind_modules)
    # the 6 forced; the total made from them is kept: they came out the same
    assert summary.counts() == {"ok": 6, "kept": 1}, summary.outcomes
    executions = (store.root / "cache" / "executions.log").read_text().splitlines()
    assert executions.count("power a^2") == 2 and executions.count("total") == 1


def test_a_worker_running_jobs_in_several_threads_is_refused_before_anything_runs(tmp_path):
    """Two jobs in one worker process would share its thread count and imports (a user's module of
    one job's folder seen by the other): the run says how to start workers instead."""
    from matrix.dask_executor import run_dask
    from matrix.errors import MatrixError
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None)
    store = Store(tmp_path / "s")
    with cluster, distributed.Client(cluster) as threaded:
        with pytest.raises(MatrixError, match=r"2 threads.*--nthreads 1"):
            run_dask(plan_of(tmp_path, store).statuses, store, threaded, kind_modules=TOY.kind_modules)
    assert not list(store.keys())


def test_ctrl_c_interrupts_a_dask_run_and_leaves_no_half_written_job(tmp_path, client):
    """outside test: with --executor dask-local three SIGINTs did nothing, the run went on to its end."""
    from matrix.dask_executor import run_dask
    store = Store(tmp_path / "s")
    plan = plan_of(tmp_path, store, sleep="8")
    slow = next(s.job for s in plan.statuses if s.job.name == "source b")
    threading.Timer(2.0, os.kill, (os.getpid(), signal.SIGINT)).start()
    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        run_dask(plan.statuses, store, client, kind_modules=TOY.kind_modules)
    assert time.monotonic() - started < 6
    assert store.result(slow.key) is None and plan_of(tmp_path, store, sleep="8").stale
    deadline = time.monotonic() + 20   # the cancelled job is gone from the workers
    while any(client.processing().values()) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(client.processing().values())


def test_dask_local_workers_get_their_share_of_the_cores_as_the_local_pool_s(monkeypatch):
    """Two workers each running torch on every core spin against each other; the local pool sets the math
    libraries' thread variables per worker, dask-local did not."""
    from matrix.dask_executor import connect
    from matrix.runs import worker_threads
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    with connect(None, workers=2) as local:
        seen = set(local.run(lambda: os.environ.get("OMP_NUM_THREADS")).values())
        local.cluster.close()
    share = worker_threads(2)
    assert seen == {None if share is None else str(share)}


def test_jobs_cut_off_by_a_lost_scheduler_say_so():
    """Outside test K4: the scheduler killed mid-run, every job said "the run stopped at the first failure
    (use --keep-going)", with no failure anywhere."""
    from types import SimpleNamespace
    from matrix.dask_executor import STOPPED, _outcome, not_finished_reason
    lost = SimpleNamespace(status="closed", scheduler=SimpleNamespace(address="tcp://lab:8786"))
    assert not_finished_reason(SimpleNamespace(status="running")) == STOPPED
    assert not_finished_reason(lost).startswith("not finished: the connection to the Dask scheduler (tcp://lab:8786) "
                                                "was lost")
    job = SimpleNamespace(key="k", name="timing x", kind="timing")
    outcome = _outcome(job, SimpleNamespace(cancelled=lambda: True), lost)
    assert outcome.status == "not_started" and "was lost" in outcome.reason
