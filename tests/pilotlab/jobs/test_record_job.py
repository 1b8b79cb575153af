"""The `record` job kind through its registered handler, and a `frames` job reading what it wrote."""
import pytest
from rosbags.highlevel import AnyReader

from matrix.kinds import KINDS
from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
from pilotlab.jobs import record as record_job  # noqa: F401  (registers "record")
from tests.pilotlab.jobs.context import context, finished

run = KINDS.get("record").handler


def test_the_record_job_writes_its_bag_into_ctx_out(stadium_csv, tmp_path):
    calls = []
    params = {"circuit": stadium_csv, "direction": "ccw", "laps": 0.1, "seed": 1, "camera": {"width": 32, "height": 24},
              "rate_hz": 10, "format": "ros2", "compressed": True, "noise": 0.1}
    ctx = context(tmp_path, "record", "record-stadium", params, progress=lambda **kw: calls.append(kw))
    result = run(ctx)
    assert result["bag"] == result["path"] == "recording" and (ctx.out / "recording" / "metadata.yaml").exists()
    assert result["termination"] == "lap_completed" and result["frames"] > 0
    assert result["topics"]["image"] == "/F1ROS/cameraL/image_raw/compressed"
    with AnyReader([ctx.out / result["bag"]]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts[result["topics"]["image"]] == result["frames"]
    assert counts["/F1ROS/cmd_vel"] == result["commands"]
    assert calls and calls[-1]["description"] == f"recording {stadium_csv} ccw"
    assert calls[-1]["completed"] >= 0.1 * 100


def test_a_frames_job_reads_the_recorded_bag(stadium_csv, tmp_path):
    record = context(tmp_path, "record", "record", {"circuit": stadium_csv, "laps": 0.1, "camera": {"width": 64, "height": 48}})
    recorded = run(record)
    frames = context(tmp_path, "frames", "frames", {"label": "stadium"}, deps={"bag": finished(record, recorded)})
    result = KINDS.get("frames").handler(frames)
    saved = FrameSet.load(frames.out)
    assert result["frames"] == len(saved) == recorded["frames"]
    assert saved.frames.shape[1:] == (66, 200, 3)
    assert 0.0 <= saved.labels[:, 0].min() and saved.labels[:, 0].max() < 14.0  # v of the expert, m/s


def test_unknown_params_are_named(stadium_csv, tmp_path):
    with pytest.raises(PilotlabError, match="unknown param 'lapz' .did you mean 'laps'..; known: camera, circuit"):
        run(context(tmp_path, "record", "typo", {"circuit": stadium_csv, "lapz": 2}))
    with pytest.raises(PilotlabError, match="circuit: Field required"):
        run(context(tmp_path, "record", "empty", {}))
