"""Incremental runs on the toy domain: exactly the jobs downstream of an edit rerun."""
import gc
import json
import importlib
import sys

import pytest

from matrix import engine
from matrix.errors import MatrixError
from matrix.execute import Schedule, run_local
from matrix.fingerprint import clear_caches
from matrix.jobs import Job
from matrix.kinds import KINDS
from matrix.recipe import load_recipe
from matrix.stale import job_status
from matrix.store import Store, outputs_hash
from tests.matrix.toydomain import TOY

RECIPE = """\
name: toy
sources:
  a: {{value: 2}}
  b: {{value: {b}}}
  c: {{value: 5{c_extra}}}
matrix:
  source: [a, b, c]
  power: [2, 3]
"""


def recipe_file(tmp_path, b=3, c_extra=""):
    path = tmp_path / "recipe.yaml"
    path.write_text(RECIPE.format(b=b, c_extra=c_extra))
    return path


def run(path, store, **options):
    recipe = load_recipe(path, TOY)
    plan = engine.make_plan(recipe, TOY, store, options.pop("force", ()))
    return plan, engine.run_plan(plan, TOY, store, **options)


def ran(summary):
    return sorted(o.name for o in summary.outcomes)


def test_first_run_runs_everything_second_nothing(tmp_path):
    store = Store(tmp_path / "store")
    plan, summary = run(recipe_file(tmp_path), store, jobs=2)
    assert len(plan.statuses) == 3 + 6 + 1 and summary.counts() == {"ok": 10}
    total = store.result(plan.statuses[-1].job.key)
    assert total["value"]["value"] == 2**2 + 2**3 + 3**2 + 3**3 + 5**2 + 5**3
    plan, summary = run(recipe_file(tmp_path), store)
    assert summary.outcomes == [] and summary.fresh == 10
    assert {s.state for s in plan.statuses} == {"fresh"}


def test_changing_one_parameter_reruns_exactly_its_downstream(tmp_path):
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)
    plan, summary = run(recipe_file(tmp_path, b=4), store)
    assert ran(summary) == ["power b^2", "power b^3", "source b", "total"]
    reasons = {s.job.name: s.reason for s in plan.statuses}
    assert reasons["source b"] == "params changed: value 3 -> 4"
    assert reasons["power b^2"] == "dependency changed: source b"
    assert reasons["power a^2"] == ""


def test_a_group_of_the_same_dependencies_in_another_order_says_so(tmp_path):
    """outside test: reordering a dataset's recordings retrained with the reason 'new' (a group's order is part of
    the job: which recording a training holds out follows it)."""
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)
    path = recipe_file(tmp_path)
    path.write_text(path.read_text().replace("source: [a, b, c]", "source: [c, b, a]"))
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    reasons = {s.job.name: s.reason for s in plan.statuses if s.state != "fresh"}
    assert reasons == {"total": "dependencies reordered: parts (a group's order is part of the job)"}


def test_a_run_stopped_before_an_edited_job_ran_leaves_the_edit_s_reasons(tmp_path, monkeypatch):
    """Outside test: after an interrupted run, `plan` said "new" for the jobs it had not reached (the
    run's record already held their new versions); it says what the edit changed until they run."""
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    with monkeypatch.context() as patched:
        patched.setattr(engine, "_run_here", interrupted)
        for _ in range(2):   # stopped twice in a row: the version the store holds is still the one compared with
            with pytest.raises(KeyboardInterrupt):
                run(recipe_file(tmp_path, b=4), store)
            plan = engine.make_plan(load_recipe(recipe_file(tmp_path, b=4), TOY), TOY, store)
            reasons = {s.job.name: s.reason for s in plan.statuses}
            assert reasons["source b"] == "params changed: value 3 -> 4"
            assert reasons["power b^2"] == "dependency changed: source b" and reasons["power a^2"] == ""
    plan, summary = run(recipe_file(tmp_path, b=4), store)
    assert ran(summary) == ["power b^2", "power b^3", "source b", "total"]
    plan = engine.make_plan(load_recipe(recipe_file(tmp_path, b=6), TOY), TOY, store)
    assert {s.job.name: s.reason for s in plan.statuses}["source b"] == "params changed: value 4 -> 6"


def test_undoing_an_edit_finds_the_old_results(tmp_path):
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)
    run(recipe_file(tmp_path, b=4), store)
    plan, summary = run(recipe_file(tmp_path), store)
    assert summary.outcomes == []


def test_failure_skips_dependents_and_reruns_next_time(tmp_path):
    store = Store(tmp_path / "store")
    plan, summary = run(recipe_file(tmp_path, c_extra=", fail: true"), store, keep_going=True)
    status = {o.name: o.status for o in summary.outcomes}
    assert status["source c"] == "failed"
    assert status["power c^2"] == status["power c^3"] == status["total"] == "skipped"
    assert status["power a^2"] == "ok"
    assert "was told to fail" in store.failure(next(s.job.key for s in plan.statuses
                                                     if s.job.name == "source c"))["error"]
    plan, _ = run(recipe_file(tmp_path, c_extra=", fail: true"), store, keep_going=True)
    reason = {s.job.name: s.reason for s in plan.statuses}["source c"]
    assert reason.startswith("failed last time: RuntimeError: source source c was told to fail")


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_job_whose_code_calls_exit_fails_with_a_reason_and_the_run_goes_on(tmp_path, jobs):
    """Outside test: a user's brain calling sys.exit(3) ended `pilotlab run` with code 3 and no word
    (SystemExit passed the process pool). Now it is that job's failure, with what to do."""
    store = Store(tmp_path / "store")
    plan, summary = run(recipe_file(tmp_path, c_extra=", fail: exit"), store, keep_going=True, jobs=jobs)
    status = {o.name: (o.status, o.reason) for o in summary.outcomes}
    assert status["source c"][0] == "failed" and "called exit(3)" in status["source c"][1]
    assert status["power a^2"][0] == "ok" and summary.failed


def test_without_keep_going_nothing_new_starts_after_a_failure(tmp_path):
    store = Store(tmp_path / "store")
    _, summary = run(recipe_file(tmp_path, c_extra=", fail: true"), store, jobs=1)
    statuses = [o.status for o in summary.outcomes]
    assert "failed" in statuses and ("not_started" in statuses or "skipped" in statuses)
    assert summary.failed


def test_not_applicable_is_cached_and_propagates(tmp_path):
    store = Store(tmp_path / "store")
    _, summary = run(recipe_file(tmp_path, c_extra=", not_applicable: true"), store)
    status = {o.name: (o.status, o.reason) for o in summary.outcomes}
    assert status["source c"] == ("not_applicable", "this source needs hardware we do not have")
    assert status["power c^2"][0] == "not_applicable" and "source c" in status["power c^2"][1]
    assert status["total"][0] == "not_applicable"
    squared = next(o for o in summary.outcomes if o.name == "power c^2")
    stored = store.result(squared.key)           # the cause's own reason, and which job it was
    assert stored["reason"] == "this source needs hardware we do not have" and stored["blocked_by"] == "source c"
    _, summary = run(recipe_file(tmp_path, c_extra=", not_applicable: true"), store)
    assert summary.outcomes == []


def test_force_reruns_one_kind_and_nothing_else(tmp_path):
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)
    plan, summary = run(recipe_file(tmp_path), store, force=["total"])
    assert ran(summary) == ["total"] and summary.counts() == {"ok": 1}   # run again, not "done elsewhere"
    executions = (store.root / "cache" / "executions.log").read_text().splitlines()
    assert executions.count("total") == 2
    _, summary = run(recipe_file(tmp_path), store)
    assert summary.outcomes == []                                         # and fresh after it
    with pytest.raises(Exception, match="did you mean 'total'"):
        run(recipe_file(tmp_path), store, force=["totl"])


def test_a_forced_job_reruns_what_was_made_from_it_in_the_same_run_if_its_outputs_changed(tmp_path):
    """Outside test: `--force offline` re-timed the networks and left the laps that replay those timings
    "fresh", showing the old timings beside the new ones. Keys are unchanged, so what stands on a job
    that runs again is planned to run after it, and runs unless that job's outputs came out the same."""
    store = Store(tmp_path / "store")
    # source c measures something new at each run; source b says how long it took (measured, not made)
    path = recipe_file(tmp_path, b="3, took: true", c_extra=", jitter: true")
    run(path, store)
    plan, summary = run(path, store, force=["source"])
    stale = {s.job.name: s.reason for s in plan.statuses}
    assert stale["power c^2"] == "dependency runs again: source c" and stale["total"].startswith("dependency runs again")
    outcomes = {o.name: o.status for o in summary.outcomes}
    assert [n for n, status in outcomes.items() if status == "ok"] == ["source a", "source b", "source c",
                                                                          "power c^2", "power c^3"]
    # same outputs (source b's run time differs: measured, not made): kept
    assert {outcomes[n] for n in ("power a^2", "power b^3", "total")} == {"kept"}
    reasons = {o.name: o.reason for o in summary.outcomes}
    assert reasons["total"] == "kept: its dependencies ran again with the outputs it was made from"
    executions = (store.root / "cache" / "executions.log").read_text().splitlines()
    assert executions.count("power c^2") == 2 and executions.count("power a^2") == 1 and executions.count("total") == 1
    _, summary = run(path, store)
    assert summary.outcomes == []


def test_a_result_made_from_a_dependency_that_ran_again_since_is_stale(tmp_path):
    """A dependency rerun under its key by a run that stopped before what stands on it (here: a run of
    one source job alone): rebuilt with the same outputs, what stands on it stays fresh; with other
    outputs (a job that is not deterministic: a timing), it is stale, by the outputs each result records."""
    store = Store(tmp_path / "store")
    path = recipe_file(tmp_path)
    run(path, store)
    forced = engine.make_plan(load_recipe(path, TOY), TOY, store, ["source"])
    outcomes = run_local([s for s in forced.statuses if s.job.name == "source a"], store,
                         kind_modules=TOY.kind_modules).outcomes
    assert [o.status for o in outcomes] == ["ok"], outcomes
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    assert {s.state for s in plan.statuses} == {"fresh"}          # the same outputs: nothing to redo
    source_a = next(s.job for s in plan.statuses if s.job.name == "source a")
    result_file = store.job_dir(source_a.key) / "result.json"
    rebuilt = json.loads(result_file.read_text())
    rebuilt["value"]["value"] += 1                                 # as a rebuild with other outputs writes it
    rebuilt["outputs"] = outputs_hash(rebuilt, ("seconds",))
    result_file.write_text(json.dumps(rebuilt))
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    stale = {s.job.name: s.reason for s in plan.statuses if s.state != "fresh"}
    assert sorted(stale) == ["power a^2", "power a^3", "total"], stale
    assert stale["power a^2"] == "dependency ran again since, with other outputs: source a"
    assert stale["total"].startswith("dependency runs again: power a^")


def test_corrupt_output_is_stale(tmp_path):
    store = Store(tmp_path / "store")
    plan, _ = run(recipe_file(tmp_path), store)
    source_a = next(s.job for s in plan.statuses if s.job.name == "source a")
    (store.artifacts(source_a.key) / "value.json").write_text("truncated")
    plan, summary = run(recipe_file(tmp_path), store)
    assert {s.job.name: s.reason for s in plan.statuses}["source a"] == "output missing or corrupt"
    assert sorted(o.name for o in summary.outcomes if o.status == "ok") == ["source a"]
    assert {o.status for o in summary.outcomes if o.name != "source a"} == {"kept"}   # rebuilt the same


KIND_MODULE = """
from matrix import job_kind

@job_kind("{kind}")
def handler(ctx):
    deps = [d.result["n"] for role in ctx.deps for d in ctx.dep_group(role)]
    return {{"n": sum(deps) + {n}}}
"""


def test_editing_a_kinds_code_reruns_that_kind_and_its_dependents(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    for name, n in (("edit_a", 1), ("edit_b", 2), ("edit_c", 3)):
        (tmp_path / f"{name}.py").write_text(KIND_MODULE.format(kind=name, n=n))
        importlib.import_module(name)
    modules = ("edit_a", "edit_b", "edit_c")
    store = Store(tmp_path / "store")

    def jobs():
        a = Job("edit_a", "a", {})
        b = Job("edit_b", "b", {}, deps={"x": a})
        return [a, b, Job("edit_c", "c", {}, deps={"x": b}), Job("edit_c", "c2", {"other": 1}, deps={"x": a})]

    statuses = [job_status(j, store, {}) for j in jobs()]
    assert run_local(statuses, store, kind_modules=modules).counts() == {"ok": 4}
    (tmp_path / "edit_b.py").write_text(KIND_MODULE.format(kind="edit_b", n=20))
    clear_caches()
    statuses = [job_status(j, store, {}) for j in jobs()]
    assert [s.state for s in statuses] == ["fresh", "new", "new", "fresh"]
    summary = run_local(statuses, store, kind_modules=modules)
    assert sorted(o.name for o in summary.outcomes) == ["b", "c"]
    assert store.result(jobs()[2].key)["value"]["n"] == 1 + 20 + 3
    for name in modules:
        KINDS._entries.pop(name)
        sys.modules.pop(name)


def test_gc_removes_only_unreachable_jobs(tmp_path):
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)
    run(recipe_file(tmp_path, b=4), store)
    keep = {j.key for j in engine.plan_jobs(load_recipe(recipe_file(tmp_path, b=4), TOY), TOY)}
    garbage = engine.find_garbage(store, keep)
    assert len(garbage.keys) == 4  # the old source b, its two powers and the old total
    engine.collect_garbage(store, garbage)
    assert set(store.keys()) == keep


def test_gc_keeps_the_unreached_jobs_the_domain_says_are_kept_elsewhere(tmp_path):
    """Outside test: gc in a cpuset (another host fingerprint) removed every timing and lap of the
    recipe; a domain can keep what this machine's plan cannot reach (pilotlab: jobs of other hosts)."""
    store = Store(tmp_path / "store")
    run(recipe_file(tmp_path), store)
    run(recipe_file(tmp_path, b=4), store)
    keep = {j.key for j in engine.plan_jobs(load_recipe(recipe_file(tmp_path, b=4), TOY), TOY)}
    old_b2 = next(k for k in store.keys() if k not in keep and store.spec(k)["name"] == "power b^2")
    store.record_failure(old_b2, {"error": "a forced rerun that failed"})     # its old result stays
    elsewhere = lambda spec: "planned elsewhere" if spec.get("key") == old_b2 else None
    garbage = engine.find_garbage(store, keep, elsewhere)
    old_b = store.spec(old_b2)["deps"]["source"]                              # what it was made from: kept too
    assert sorted(store.spec(k)["name"] for k in garbage.keys) == ["power b^3", "total"]
    assert garbage.elsewhere == {old_b2: "planned elsewhere"}
    engine.collect_garbage(store, garbage)
    assert set(store.keys()) == keep | {old_b2, old_b}


def test_what_a_job_prints_at_the_fd_level_goes_to_its_log(tmp_path, capfd):
    store = Store(tmp_path / "store")
    plan, summary = run(recipe_file(tmp_path, c_extra=", noise: true"), store)
    assert summary.counts() == {"ok": 10}
    source_c = next(s.job for s in plan.statuses if s.job.name == "source c")
    assert "C-level noise" in (store.job_dir(source_c.key) / "log.txt").read_text()
    assert "C-level noise" not in capfd.readouterr().err


def test_a_library_handler_made_in_one_job_logs_into_the_next_jobs_log(tmp_path):
    """A handler bound to sys.stderr during job 1 wrote to job 1's closed log in job 2 ("Logging error")."""
    store = Store(tmp_path / "store")
    path = tmp_path / "recipe.yaml"
    path.write_text(RECIPE.format(b="3, library_log: true", c_extra=", library_log: true"))
    plan, summary = run(path, store, jobs=1)
    assert summary.counts() == {"ok": 10}
    for name in ("b", "c"):
        source = next(s.job for s in plan.statuses if s.job.name == f"source {name}")
        log = (store.job_dir(source.key) / "log.txt").read_text()
        assert f"library warning from source {name}" in log and "Logging error" not in log


def test_workers_share_the_cores_among_their_math_libraries(tmp_path, monkeypatch):
    """With -j N each worker's OpenMP/BLAS libraries get cores // N threads (not every core each)."""
    from matrix.runs import default_jobs, worker_threads
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    store = Store(tmp_path / "store")
    plan, summary = run(recipe_file(tmp_path), store, jobs=2)
    sources = [s.job for s in plan.statuses if s.job.kind == "source"]
    expected = None if default_jobs() < 2 else str(worker_threads(2))
    assert {store.result(job.key)["value"]["omp_threads"] for job in sources} == {expected}
    assert worker_threads(1) is None                       # one worker: the libraries' own default
    assert default_jobs() < 2 or worker_threads(2) == default_jobs() // 2


@pytest.mark.parametrize("arguments, message", [
    (("local", 0), "give 1 or more"),
    (("dask", 1), "needs --scheduler"),
    (("local", 1, "tcp://host:8786"), "is for --executor dask"),
    (("local", 1, None, "TIMING"), "use it with --executor dask"),
])
def test_executor_settings_that_make_no_sense_are_errors(arguments, message):
    with pytest.raises(MatrixError, match=message):
        engine.Executor(*arguments)


def test_a_dependency_under_two_roles_makes_its_dependent_ready_once():
    shared = Job("source", "shared", {"value": 1})
    both = Job("source", "both", {"value": 2}, deps={"timing": shared, "reference": shared})
    schedule = Schedule([shared, both])
    assert schedule.ready_keys() == [shared.key]
    assert schedule.next_ready() == shared
    schedule.done(shared.key)
    assert schedule.ready_keys() == [both.key]
    assert schedule.next_ready() == both and schedule.next_ready() is None


def test_a_kind_exclusive_for_some_params_runs_those_jobs_alone_and_the_others_beside_work():
    from matrix.kinds import register_kind
    kind = register_kind("lap_toy", lambda ctx: {}, exclusive_for=lambda params: params["clock"] == "host")
    try:
        on_host, replayed = Job("lap_toy", "timed", {"clock": "host"}), Job("lap_toy", "replayed", {"clock": "sim"})
        assert kind.runs_alone(on_host.params) and not kind.runs_alone(replayed.params)
        schedule = Schedule([on_host, replayed])
        assert schedule.take(False, 1, 2) == replayed      # beside a running job: only the replayed one
        assert schedule.take(False, 1, 2) is None          # the timed one waits for an idle host
        assert schedule.take(False, 0, 2) == on_host
    finally:
        KINDS._entries.pop("lap_toy")


@pytest.fixture
def alone_toy():
    """A kind whose jobs run alone (as timings do), registered for one test."""
    from matrix.kinds import register_kind
    register_kind("alone_toy", lambda ctx: {}, exclusive=True)
    yield "alone_toy"
    KINDS._entries.pop("alone_toy")


def test_the_critical_path_starts_first_and_a_long_job_nothing_needs_does_not_hold_it_up(alone_toy):
    """The study's first minutes: a reference lap (nothing but the report needs it) was ready when the
    training (run alone, every later job waits on it) was, started beside the last recording, and
    the training waited two minutes for it."""
    reference_lap = Job("source", "reference lap", {"value": 1})
    recording = Job("source", "recording", {"value": 2})
    training = Job("alone_toy", "training", {}, deps={"data": recording})
    evaluation = Job("power", "evaluation", {"power": 2}, deps={"source": training})
    schedule = Schedule([reference_lap, recording, training, evaluation])
    assert schedule.take(False, 0, 2) == recording        # the longest chain first, not plan order
    assert schedule.take(False, 1, 2) == reference_lap    # nothing ready outranks it yet
    schedule = Schedule([reference_lap, recording, training, evaluation])
    schedule.take(False, 0, 2)
    schedule.done(recording.key)
    assert schedule.take(False, 1, 2) is None             # the training outranks the lap: both wait
    assert schedule.take(False, 0, 2) == training         # the host is idle: the training runs alone
    assert schedule.take(True, 1, 2) is None


def test_an_exclusive_job_waiting_for_the_host_lets_only_work_that_ends_before_it_start(alone_toy):
    """Backfilling: the quickstart's timings waited for the last fine-tune while the other core idled,
    and the reference laps, which nothing needs, ran last. A job the waiting timing outranks starts
    beside the running one only if it is expected to end first (the timing then starts no later)."""
    import time
    fine_tune, recording = Job("source", "fine-tune", {"value": 1}), Job("source", "recording", {"value": 2})
    timing = Job("alone_toy", "timing", {}, deps={"data": recording})
    trainings = [Job("power", f"training {i}", {"power": i}, deps={"source": timing}) for i in (2, 3)]
    fits, too_long = Job("source", "reference lap", {"value": 3}), Job("source", "search", {"value": 4})
    conversion = Job("power", "conversion", {"power": 2}, deps={"source": fits})
    seconds = {fine_tune.key: 60.0, recording.key: 40.0, timing.key: 3.0, fits.key: 20.0, too_long.key: 50.0,
               conversion.key: 5.0, **{t.key: 100.0 for t in trainings}}
    schedule = Schedule([fine_tune, recording, timing, *trainings, fits, too_long, conversion],
                        lambda job: seconds[job.key])
    assert schedule.take(False, 0, 3) == recording          # 143 s of work wait on it
    assert schedule.take(False, 1, 3) == fine_tune          # then the longest (the timing is 40 s away)
    schedule.done(recording.key)                            # the timing is ready: it waits for the host
    schedule.started[fine_tune.key] = time.monotonic() - 30   # 30 s of the fine-tune's 60 are left
    assert schedule.take(False, 1, 3) == fits               # 20 s ends before; the 50 s search would not
    assert schedule.take(False, 2, 3) is None
    schedule.done(fits.key)
    schedule.started[fine_tune.key] -= 60                   # 90 s in, past its estimate: a quarter of that
    assert schedule.take(False, 1, 3) == conversion         # again is expected (22.5 s), so 5 s fit
    schedule.done(conversion.key)
    assert schedule.take(False, 1, 3) is None              # the 50 s search does not
    schedule.done(fine_tune.key)
    assert schedule.take(False, 0, 3) == timing             # an idle host: the timing runs alone
    assert schedule.take(True, 1, 3) is None


def test_a_job_that_runs_alone_is_waited_for_once_its_last_dependencies_run(alone_toy):
    """The study's training (it runs alone) needed four recordings' frames; when the first of the last
    two ended, a 76 s reference lap took the free core, and the training waited for it. From the moment
    every dependency it still needs is running, only work that ends before them starts."""
    import time
    frames = [Job("source", f"frames {i}", {"value": i}) for i in (1, 2)]
    training = Job("alone_toy", "training", {}, deps={"a": frames[0], "b": frames[1]})
    evaluation = Job("power", "evaluation", {"power": 2}, deps={"source": training})
    lap, quick = Job("source", "reference lap", {"value": 3}), Job("source", "quick", {"value": 4})
    seconds = {frames[0].key: 5.0, frames[1].key: 5.0, training.key: 100.0, evaluation.key: 50.0,
               lap.key: 76.0, quick.key: 1.0}
    schedule = Schedule([*frames, training, evaluation, lap, quick], lambda job: seconds[job.key])
    assert [schedule.take(False, n, 2) for n in (0, 1)] == frames
    schedule.done(frames[0].key)
    assert schedule.take(False, 1, 2) == quick             # it ends before the other frames job
    schedule.done(quick.key)
    assert schedule.take(False, 1, 2) is None              # the lap would hold the training up
    schedule.done(frames[1].key)
    assert schedule.take(False, 0, 2) == training
    assert schedule.take(True, 1, 2) is None
    schedule.done(training.key)
    assert {schedule.take(False, 0, 2), schedule.take(False, 1, 2)} == {evaluation, lap}


def test_a_free_core_is_not_kept_long_for_a_job_that_is_not_ready(alone_toy):
    """A timing waits for its fine-tune, a minute from its end: a 100 s lap takes the free core (the
    timing waits 40 s more; the core would have idled 60)."""
    fine_tune, other = Job("source", "fine-tune", {"value": 1}), Job("source", "other", {"value": 2})
    timing = Job("alone_toy", "timing", {}, deps={"model": fine_tune})
    evaluation = Job("power", "evaluation", {"power": 2}, deps={"source": timing})
    lap = Job("source", "lap", {"value": 3})
    seconds = {fine_tune.key: 60.0, other.key: 1.0, timing.key: 3.0, evaluation.key: 120.0, lap.key: 100.0}
    schedule = Schedule([fine_tune, other, timing, evaluation, lap], lambda job: seconds[job.key])
    assert schedule.take(False, 0, 2) == fine_tune and schedule.take(False, 1, 2) == lap


def test_without_estimates_nothing_is_backfilled(alone_toy):
    """Ranked by chains of jobs, not seconds, nothing says what would end before the running jobs."""
    fine_tune, recording = Job("source", "fine-tune", {"value": 1}), Job("source", "recording", {"value": 2})
    timing = Job("alone_toy", "timing", {}, deps={"data": recording})
    training = Job("power", "training", {"power": 2}, deps={"source": timing})
    lap = Job("source", "reference lap", {"value": 3})
    schedule = Schedule([fine_tune, recording, timing, training, lap])
    assert schedule.take(False, 0, 3) == recording and schedule.take(False, 1, 3) == fine_tune
    schedule.done(recording.key)
    assert schedule.take(False, 1, 3) is None               # the lap waits with the timing
    schedule.done(fine_tune.key)
    assert schedule.take(False, 0, 3) == timing


@pytest.mark.parametrize("freeze_from, frozen", [(10_000, False), (1, True)])
def test_planning_pauses_the_collector_and_freezes_only_after_a_large_plan(tmp_path, monkeypatch, freeze_from,
                                                                        frozen):
    monkeypatch.setattr(engine, "FREEZE_FROM_JOBS", freeze_from)
    recipe = load_recipe(recipe_file(tmp_path), TOY)
    gc.unfreeze()
    try:
        plan = engine.make_plan(recipe, TOY, Store(tmp_path / "store"))
        assert gc.isenabled() and len(plan.statuses) == 10   # 3 sources, 6 powers, their total
        assert (gc.get_freeze_count() > 0) == frozen
    finally:
        gc.unfreeze()


def test_a_chatty_job_s_log_keeps_its_start_and_end(tmp_path):
    from matrix.worker import _cap_log
    log = tmp_path / "log.txt"
    log.write_bytes(b"first line\n" + b"x" * 5_000_000 + b"\nlast line\n")
    _cap_log(log, limit=1000)
    text = log.read_text()
    assert text.startswith("first line\n") and text.endswith("\nlast line\n") and len(text) < 1200
    assert "bytes of output cut: the log keeps its first and last 500 bytes" in text
    small = tmp_path / "small.txt"
    small.write_text("short\n")
    _cap_log(small, limit=1000)
    assert small.read_text() == "short\n"
