"""A lab of machines on Dask: a timing job has its own host to itself, not the cluster.

Two Dask workers stand for two hosts (each with its own $MATRIX_HOST and host lock, and its own worker
resource). A source's measure (timing) jobs go only to the worker declaring its resource; timing jobs on
different hosts run at once; no job runs beside a timing job on its host."""
import pytest

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from tests.matrix.test_parallel import intervals
from tests.matrix.toydomain import TOY

distributed = pytest.importorskip("distributed")

RECIPE = """\
name: hosts
sources:
  a: {value: 2, worker: ON_A}
  b: {value: 3, worker: ON_B}
matrix:
  source: [a, b]
  power: [1, 2, 3, 4]
sleep: 0.4
measures: true
"""


def host(name: str, resource: str, locks, process: int) -> dict:
    """One of the worker processes of host `name` to the engine (single-threaded, as `dask worker --nthreads
    1 --nworkers 2` starts them): two per host, so a job could run beside a timing job there if the host
    lock let it."""
    env = {"MATRIX_HOST": name, "MATRIX_HOST_LOCK": str(locks / f"{name}.lock")}
    return {"cls": distributed.Nanny, "options": {"nthreads": 1, "resources": {resource: 1}, "env": env,
                                                  "name": f"{name}-{process}"}}


def overlap(one, other) -> bool:
    return one[1] < other[2] and other[1] < one[2]


def test_a_timing_job_has_its_host_alone_and_the_other_host_goes_on(tmp_path):
    from matrix.dask_executor import run_dask
    path = tmp_path / "r.yaml"
    path.write_text(RECIPE)
    store = Store(tmp_path / "store")
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    workers = {f"{side}{process}": host(f"host-{side}", f"ON_{side.upper()}", tmp_path, process)
               for side in "ab" for process in (1, 2)}
    scheduler = {"cls": distributed.Scheduler, "options": {"dashboard_address": None}}
    with distributed.SpecCluster(workers=workers, scheduler=scheduler) as cluster, distributed.Client(cluster) as client:
        summary = run_dask(plan.statuses, store, client, kind_modules=TOY.kind_modules)
    assert summary.counts() == {"ok": 2 + 8 + 8 + 1}, summary.outcomes
    runs = intervals(store)
    timings = [run for run in runs if run[0] == "measure"]
    assert {(name.split()[2][0], on) for _, _, _, name, on in timings} == {("a", "host-a"), ("b", "host-b")}
    assert any(overlap(one, other) for one in timings for other in timings if one[4] != other[4])
    for timing in timings:
        beside = [run for run in runs if run[3] != timing[3] and run[4] == timing[4] and overlap(run, timing)]
        assert not beside, f"{timing[3]} ran beside {beside} on {timing[4]}"
