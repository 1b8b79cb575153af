import logging

import pytest
from rosbags.highlevel import AnyReader

from matrix.kinds import KINDS, JobContext
from pilotlab.errors import PilotlabError
from pilotlab.jobs import record as record_job  # noqa: F401  (registers the kind)


def context(tmp_path, params, progress=None):
    out = tmp_path / "out"
    out.mkdir(parents=True)
    return JobContext(key="k", kind="record", name="record/test", params=params, deps={}, out=out,
                      cache=tmp_path / "cache", log=logging.getLogger("test"),
                      _progress=progress or (lambda **_: None))


def test_the_record_job_writes_its_bag_into_ctx_out(stadium_csv, tmp_path):
    calls = []
    params = {"circuit": stadium_csv, "direction": "ccw", "laps": 0.1, "seed": 1, "width": 32, "height": 24,
              "rate_hz": 10, "format": "ros2", "compressed": True, "noise": 0.1}
    ctx = context(tmp_path, params, progress=lambda **kw: calls.append(kw))
    result = KINDS.get("record").handler(ctx)
    assert result["path"] == "recording" and (ctx.out / "recording" / "metadata.yaml").exists()
    assert result["termination"] == "lap_completed" and result["frames"] > 0
    assert result["topics"]["image"] == "/F1ROS/cameraL/image_raw/compressed"
    with AnyReader([ctx.out / result["path"]]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts[result["topics"]["image"]] == result["frames"]
    assert counts["/F1ROS/cmd_vel"] == result["commands"]
    assert calls and calls[-1]["description"] == f"recording {stadium_csv} ccw"
    assert calls[-1]["completed"] >= 0.1 * 100


def test_unknown_params_are_named(stadium_csv, tmp_path):
    with pytest.raises(PilotlabError, match="unknown param.*lapz.*known: circuit"):
        KINDS.get("record").handler(context(tmp_path, {"circuit": stadium_csv, "lapz": 2}))
    with pytest.raises(PilotlabError, match="'circuit' is required"):
        KINDS.get("record").handler(context(tmp_path / "again", {}))
