"""The `frames` job kind, run through its registered handler with a hand-made JobContext."""
import json

import numpy as np
import pytest

from matrix.kinds import KINDS, DepResult
from pilotlab.data.frames import FrameSet
from pilotlab.data.preprocess import PreprocessConfig, preprocess
from pilotlab.errors import PilotlabError
from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
from tests.pilotlab.data.bagfiles import drive_bag, images
from tests.pilotlab.data.test_folder import make_folder
from tests.pilotlab.jobs.context import context

run = KINDS.get("frames").handler


def test_a_user_bag_given_as_input(tmp_path):
    frames = images(5, 120, 160)
    drive_bag(tmp_path / "user", "mcap", frames, first_command=1)
    progress = []
    ctx = context(tmp_path, "frames", "frames-user", {"crop_top": 0.4, "label": "user run"},
                  inputs={"bag": tmp_path / "user"}, progress=lambda **kw: progress.append(kw))
    result = run(ctx)
    json.dumps(result)  # JSON-serialisable
    saved = FrameSet.load(ctx.out)
    config = PreprocessConfig(crop_top=0.4)
    np.testing.assert_array_equal(saved.frames, np.stack([preprocess(f, config) for f in frames[1:]]))
    assert result["frames"] == 4 and result["dropped"] == 1 and result["format"] == "ros2-mcap"
    assert result["image_size"] == [120, 160] and result["label"] == "user run"
    assert result["duration_s"] == pytest.approx(0.3) and result["preprocess"] == config.as_dict()
    assert result["v_range"] == pytest.approx([1.1, 1.4]) and result["w_range"] == pytest.approx([-0.25, -0.1])
    assert progress[-1]["completed"] == progress[-1]["total"] == 4


def test_a_bag_recorded_by_a_record_job(tmp_path):
    artifacts = tmp_path / "record-out"
    artifacts.mkdir()
    drive_bag(artifacts / "lap.bag", "ros1", images(3))
    record = DepResult(key="rec", kind="record", params={}, result={"path": "lap.bag"}, artifacts=artifacts)
    ctx = context(tmp_path, "frames", "frames-rec", deps={"bag": record})
    assert run(ctx)["frames"] == 3 and len(FrameSet.load(ctx.out)) == 3


def test_a_deeplearningstudio_folder(tmp_path):
    folder = make_folder(tmp_path / "dls", images(3))
    ctx = context(tmp_path, "frames", "frames-dls", inputs={"bag": folder})
    result = run(ctx)
    assert result["format"] == "folder" and result["frames"] == 3


def test_exactly_one_source_and_known_params(tmp_path):
    drive_bag(tmp_path / "a.bag", "ros1", images(2))
    with pytest.raises(PilotlabError, match="reads exactly one recording .* it was given 0"):
        run(context(tmp_path, "frames", "none"))
    record = DepResult(key="rec", kind="record", params={}, result={"path": "a.bag"}, artifacts=tmp_path)
    with pytest.raises(PilotlabError, match="it was given 2"):
        run(context(tmp_path, "frames", "two", deps={"bag": record}, inputs={"bag": tmp_path / "a.bag"}))
    with pytest.raises(PilotlabError, match="unknown param 'crop' .did you mean 'crop_top'..; known: command_topic, crop_bottom"):
        run(context(tmp_path, "frames", "typo", {"crop": 0.5}, inputs={"bag": tmp_path / "a.bag"}))


def test_a_path_param_works_for_jobs_built_by_hand(tmp_path):
    drive_bag(tmp_path / "b", "sqlite3", images(2))
    assert run(context(tmp_path, "frames", "path", {"path": str(tmp_path / "b")}))["frames"] == 2
