"""Job keys: canonical JSON, sha256, golden values that pin the format."""
import math

import pytest

from matrix.jobs import InputFile, Job, UnserialisableError, canonical_json, input_file, make_key
from tests.matrix import toydomain  # noqa: F401  (registers the toy kinds)


def test_canonical_json_sorts_keys_and_drops_spaces():
    assert canonical_json({"b": [1, 2.5, None], "a": {"y": True, "x": "é"}}) == \
        '{"a":{"x":"é","y":true},"b":[1,2.5,null]}'


def test_golden_key_pins_the_format():
    # sha256 of '{"code":"00…0","deps":{"data":["ab","cd"]},"format":1,"inputs":{"bag":"ef"},
    #             "kind":"train","params":{"epochs":20,"lr":0.001}}'
    key = make_key("train", {"epochs": 20, "lr": 0.001}, {"data": ["ab", "cd"]}, {"bag": "ef"}, "0" * 64)
    assert key == "935508eccd334eeb326719318c1b3d5e7d95799d3144e277e4359a406e94a3f1"


def test_golden_key_of_an_empty_job():
    assert make_key("noop", {}, {}, {}, "") == \
        "801d3eee219c57d6fda717edb8bb89289bdf25e8bcab3584c86735ebeec2fba3"


def test_a_jobs_key_is_make_key_of_its_parts():
    # Job.key writes the canonical JSON from its jobs and files directly: the same text as make_key's
    source = Job("source", "s", {"value": 1})
    other = Job("source", "t", {"value": 2})
    job = Job("power", "p", {"power": 3, "é": [1, {"b": None, "a": 2.5}]},
              deps={"z": source, "a": (other, source), "m": [source]},
              inputs={"bag": InputFile("x.bag", "ef" * 32), "b\"ad": InputFile("y", "01" * 32)})
    assert job.key == make_key("power", dict(job.params), {"z": source.key, "a": [other.key, source.key],
                                                          "m": [source.key]},
                               {"bag": "ef" * 32, "b\"ad": "01" * 32}, job.code)
    assert Job("source", "n").key == make_key("source", {}, {}, {}, Job("source", "n").code)


@pytest.mark.parametrize("bad", [{1: "int key"}, {"x": {1, 2}}, {"x": object()}, {"x": math.nan},
                                 {"x": b"bytes"}, {"x": math.inf}])
def test_unserialisable_params_are_errors(bad):
    with pytest.raises(UnserialisableError):
        Job("source", "bad", bad)


def test_key_changes_with_params_deps_and_inputs(tmp_path):
    a = Job("source", "a", {"value": 1, "sleep": 0, "fail": False, "not_applicable": False})
    b = Job("source", "a", {"value": 2, "sleep": 0, "fail": False, "not_applicable": False})
    assert a.key != b.key
    assert Job("power", "p", {"power": 2}, deps={"source": a}).key != \
        Job("power", "p", {"power": 2}, deps={"source": b}).key
    file = tmp_path / "f.bin"
    file.write_bytes(b"one")
    first = Job("source", "a", dict(a.params), inputs={"bag": input_file(str(file))})
    file.write_bytes(b"two")
    second = Job("source", "a", dict(a.params), inputs={"bag": input_file(str(file))})
    assert first.key != second.key != a.key


def test_name_does_not_enter_the_key_and_equal_jobs_are_shared():
    params = {"value": 1, "sleep": 0, "fail": False, "not_applicable": False}
    assert Job("source", "a", params) == Job("source", "another name", dict(params))
    assert len({Job("source", "a", params), Job("source", "a", dict(params))}) == 1


def test_moving_an_input_file_keeps_the_key(tmp_path):
    one, two = tmp_path / "one.bag", tmp_path / "two.bag"
    one.write_bytes(b"same")
    two.write_bytes(b"same")
    assert Job("source", "a", {}, inputs={"bag": input_file(str(one))}).key == \
        Job("source", "a", {}, inputs={"bag": input_file(str(two))}).key


def test_jobs_are_frozen():
    job = Job("source", "a", {"value": 1})
    with pytest.raises(Exception):
        job.params["value"] = 2
    with pytest.raises(Exception):
        job.kind = "other"


def test_an_inputs_parts_are_in_its_record_not_its_key_and_plan_names_the_part_that_changed():
    from matrix.stale import own_changes
    parts = (("net.py", "aa" * 32), ("helper.py", "bb" * 32))
    job = Job("power", "p", {"power": 2}, inputs={"source": InputFile("net.py", "ef" * 32, parts)})
    assert job.key == Job("power", "p", {"power": 2}, inputs={"source": InputFile("net.py", "ef" * 32)}).key
    before = job.spec()
    assert before["inputs"]["source"] == {"path": "net.py", "sha256": "ef" * 32, "parts": dict(parts)}
    edited = Job("power", "p", {"power": 2}, inputs={"source": InputFile(
        "net.py", "01" * 32, (("net.py", "aa" * 32), ("helper.py", "cc" * 32), ("new.py", "dd" * 32)))})
    assert own_changes(edited, before) == ["input changed: source (helper.py, new.py)"]
    before["inputs"]["source"].pop("parts")    # stored before inputs had parts: its path, as it was
    assert own_changes(edited, before) == ["input changed: source (net.py)"]


def test_a_dependency_added_or_removed_is_said_so():
    """Outside test: a lap that lost a dependency (a recipe setting dropped it) was planned as "not in the
    store: the last run did not finish it", and one that gained one as "dependency changed"."""
    from matrix.stale import dependency_changes
    a, b = Job("source", "source a", {"value": 1}), Job("source", "source b", {"value": 2})
    with_hint = Job("power", "p", {"power": 2}, deps={"base": a, "hint": b})
    plain = Job("power", "p", {"power": 2}, deps={"base": a})
    assert dependency_changes(plain, with_hint.spec()) == ["dependency removed: hint"]
    assert dependency_changes(with_hint, plain.spec()) == ["dependency added: hint (source b)"]
    assert dependency_changes(Job("power", "p", {"power": 2}, deps={"base": b}), plain.spec()) == \
        ["dependency changed: source b"]
