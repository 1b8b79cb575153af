"""The store records each output's sha256: a stored file replaced by another of the same size is
never read as the job's output; the job is stale ("output changed") and the next run rebuilds it."""
import json
import os
from unittest import mock

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from matrix.store import _signature as store_signature
from tests.matrix.toydomain import TOY

RECIPE = """\
name: toy
sources:
  a: {value: 2}
  b: {value: 3}
matrix:
  source: [a, b]
  power: [2]
"""


def plan_and_run(path, store, force=()):
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store, force)
    return plan, engine.run_plan(plan, TOY, store)


def executions(store):
    return (store.cache / "executions.log").read_text().splitlines()


def setup(tmp_path):
    path, store = tmp_path / "recipe.yaml", Store(tmp_path / "store")
    path.write_text(RECIPE)
    plan, _ = plan_and_run(path, store)
    source_a = next(s.job.key for s in plan.statuses if s.job.name == "source a")
    return path, store, source_a


def status_of(path, store, name):
    plan = engine.make_plan(load_recipe(path, TOY), TOY, store)
    return next(s for s in plan.statuses if s.job.name == name)


def test_result_records_each_outputs_sha256(tmp_path):
    _, store, key = setup(tmp_path)
    entry = store.result(key)["manifest"]["value.json"]
    assert entry["size"] == 1 and len(entry["sha256"]) == 64


def test_a_same_size_replacement_makes_the_job_stale_and_the_run_rebuilds_it(tmp_path):
    path, store, key = setup(tmp_path)
    (store.artifacts(key) / "value.json").write_text("7")           # same size, other content
    status = status_of(path, store, "source a")
    assert (status.state, status.reason) == ("stale", "output changed")
    _, summary = plan_and_run(path, store)
    assert [o.name for o in summary.outcomes if o.status == "ok"] == ["source a"]   # what stands on it: kept
    assert summary.counts() == {"ok": 1, "kept": 2}
    assert (store.artifacts(key) / "value.json").read_text() == "2"
    assert status_of(path, store, "source a").state == "fresh"


def test_an_output_put_back_as_it_was_is_fresh_again(tmp_path):
    """Outside test: a file changed, then put back byte for byte, left the job stale for good (the
    "changed" mark was never looked at again)."""
    path, store, key = setup(tmp_path)
    target = store.artifacts(key) / "value.json"
    target.write_text("7")
    assert status_of(path, store, "source a").reason == "output changed"
    assert status_of(path, store, "source a").reason == "output changed"      # still, not hashed again
    target.write_text("2")
    assert status_of(path, store, "source a").state == "fresh"


def test_a_replacement_that_puts_back_size_mtime_and_inode_is_found_by_plan(tmp_path):
    """Outside test: an artifact rewritten in place, its mtime put back (`touch -r`), was fresh to `plan`;
    the change time, which no one can set, tells."""
    path, store, key = setup(tmp_path)
    target = store.artifacts(key) / "value.json"
    before = target.stat()
    target.write_text("7")
    os.utime(target, ns=(before.st_atime_ns, before.st_mtime_ns))    # same size, mtime and inode
    status = status_of(path, store, "source a")
    assert (status.state, status.reason) == ("stale", "output changed")


def test_a_verified_json_of_three_numbers_per_file_is_still_read(tmp_path):
    """Stores written before the change time was kept are not hashed again in full."""
    path, store, key = setup(tmp_path)
    verified = store.job_dir(key) / "verified.json"
    verified.write_text(json.dumps({name: mark[:3] for name, mark in json.loads(verified.read_text()).items()}))
    calls = []
    with mock.patch("matrix.store.file_sha256", side_effect=lambda p: calls.append(p)):
        assert status_of(path, store, "source a").state == "fresh"
    assert calls == []


def test_a_replacement_that_keeps_the_stat_is_caught_before_a_job_reads_it(tmp_path):
    path, store, key = setup(tmp_path)
    target = store.artifacts(key) / "value.json"
    target.write_text("7")
    # the stat check cannot tell (as on a file system whose times are too coarse): the stat recorded as hashed
    verified = store.job_dir(key) / "verified.json"
    verified.write_text(json.dumps({"value.json": store_signature(target.stat())}))
    assert status_of(path, store, "source a").state == "fresh"
    _, summary = plan_and_run(path, store, force=["power"])
    failed = {o.name: o.reason for o in summary.outcomes if o.status == "failed"}
    assert "output changed" in failed["power a^2"] and executions(store).count("power a^2") == 1
    status = status_of(path, store, "source a")
    assert (status.state, status.reason) == ("stale", "output changed")


def test_a_manifest_of_sizes_only_still_reads_as_intact(tmp_path):
    _, store, key = setup(tmp_path)
    result = dict(store.result(key), manifest={"value.json": 1})
    assert store.outputs_intact(key, result)
    assert not store.outputs_intact(key, dict(result, manifest={"value.json": 2}))


def test_an_entry_whose_spec_was_deleted_is_not_fresh_and_the_run_rebuilds_it(tmp_path):
    path, store, key = setup(tmp_path)
    (store.job_dir(key) / "spec.json").unlink()
    status = status_of(path, store, "source a")
    assert (status.state, status.reason) == ("stale", "output missing or corrupt")
    _, summary = plan_and_run(path, store)
    assert [o.name for o in summary.outcomes if o.status == "ok"] == ["source a"]   # what stands on it: kept
    assert summary.counts() == {"ok": 1, "kept": 2}
    assert store.spec(key)["key"] == key and status_of(path, store, "source a").state == "fresh"


def test_a_stored_job_whose_result_json_is_damaged_is_stale_not_new(tmp_path):
    """Outside test: a job whose result.json was damaged was planned as "new", as if it had never run."""
    recipe = tmp_path / "r.yaml"
    recipe.write_text("name: toy\nsources:\n  a: {value: 2}\nmatrix:\n  source: [a]\n  power: [2]\n")
    store = Store(tmp_path / "s")
    engine.run_plan(engine.make_plan(load_recipe(recipe, TOY), TOY, store), TOY, store)
    key = engine.make_plan(load_recipe(recipe, TOY), TOY, store).statuses[0].job.key
    (store.job_dir(key) / "result.json").write_text("{not json")
    status = engine.make_plan(load_recipe(recipe, TOY), TOY, store).statuses[0]
    assert (status.state, status.reason) == ("stale", "stored result missing or corrupt (result.json)")


def test_an_artifact_named_changed_is_checked_as_any_other(tmp_path):
    """verified.json's mark of a changed file once shared its names with the artifacts': an artifact
    called `changed` read as that mark."""
    import hashlib
    _, store, key = setup(tmp_path)
    (store.artifacts(key) / "changed").write_text("x")
    manifest = {**store.result(key)["manifest"], "changed": {"size": 1, "sha256": hashlib.sha256(b"x").hexdigest()}}
    result = dict(store.result(key), manifest=manifest)
    assert store.outputs_state(key, result) == store.outputs_state(key, result) == ""   # intact, twice
    (store.artifacts(key) / "changed").write_text("y")
    assert store.outputs_state(key, result, full=True) == "changed"
    (store.artifacts(key) / "changed").write_text("x")
    assert store.outputs_state(key, result) == ""


def test_a_dependency_is_hashed_in_full_once_per_run(tmp_path):
    """The study's jobs hashed 14 GB of their dependencies' files before reading them, the training
    frames 48 times over. A run hashes a dependency's files in full once (none that it made itself: their
    commit hashed them); the stat check stands for it afterwards, within that run only."""
    _, store, key = setup(tmp_path)
    result = store.result(key)
    calls = []
    hashing = mock.patch("matrix.store.file_sha256", side_effect=lambda p: calls.append(p) or
                         result["manifest"]["value.json"]["sha256"])
    with hashing:
        assert store.outputs_state(key, result, full=True, run="next") == ""
        assert len(calls) == 1                                               # made by an earlier run
        assert store.outputs_state(key, result, full=True, run="next") == ""
        assert len(calls) == 1                                               # hashed in full by this one
        assert store.outputs_state(key, result, full=True) == "" and len(calls) == 2   # no run: every time
    made = json.loads((store.job_dir(key) / "verified.json").read_text())["/hashed in full by run"]
    assert made == "next"
    target = store.artifacts(key) / "value.json"
    target.write_text("7")                                                   # changed within the run: its
    assert store.outputs_state(key, result, full=True, run="next") == "changed"   # stat tells


def test_what_a_run_commits_is_not_hashed_in_full_again_in_that_run(tmp_path):
    store = Store(tmp_path / "store")
    spec = {"key": "ab" * 32, "kind": "source", "name": "made", "params": {}, "deps": {}, "inputs": {}}
    workdir = store.new_workdir(spec["key"])
    (workdir / "artifacts").mkdir(exist_ok=True)
    (workdir / "artifacts" / "frames.npy").write_bytes(b"x" * 1000)
    store.commit(spec["key"], workdir, spec, {"status": "ok", "value": {}}, run="this run")
    result = store.result(spec["key"])
    with mock.patch("matrix.store.file_sha256") as hashed:
        assert store.outputs_state(spec["key"], result, full=True, run="this run") == ""
    assert not hashed.called
