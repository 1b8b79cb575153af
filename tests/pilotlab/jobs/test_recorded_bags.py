"""Bags written by our recorder (the `record` job) read back the same in ROS1 and ROS2."""
import numpy as np

from matrix.kinds import KINDS
from pilotlab.data.bags import open_bag, read_commands
from pilotlab.data.frames import FrameSet
from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
from pilotlab.jobs import record as record_job  # noqa: F401  (registers "record")
from tests.pilotlab.jobs.context import context, finished

SHORT = {"circuit": "simple_circuit", "camera": {"width": 160, "height": 120}, "max_seconds": 2.0}


def recorded_frames(tmp_path, fmt, compressed=None):
    record = context(tmp_path, "record", f"record-{fmt}-{compressed}", {**SHORT, "format": fmt, "compressed": compressed})
    dep = finished(record, KINDS.get("record").handler(record))
    frames = context(tmp_path, "frames", f"frames-{fmt}-{compressed}", deps={"bag": dep})
    result = KINDS.get("frames").handler(frames)
    return FrameSet.load(frames.out), result, record.out / dep.result["path"]


def test_ros1_and_ros2_recordings_give_the_same_frames_and_labels(tmp_path):
    ros1, result1, bag1 = recorded_frames(tmp_path, "ros1")
    ros2, result2, _ = recorded_frames(tmp_path, "ros2")
    assert result1["format"] == "ros1" and result2["format"] == "ros2-sqlite3"
    assert len(ros1) == 20 and result1["dropped"] == 0
    np.testing.assert_array_equal(ros1.frames, ros2.frames)
    np.testing.assert_array_equal(ros1.labels, ros2.labels)
    with open_bag(bag1) as reader:                       # each frame has the expert's command of its stamp
        stamps, commands, _ = read_commands(reader, bag1, "/F1ROS/cmd_vel")
    np.testing.assert_array_equal(ros1.labels, commands[np.isin(stamps, stamps[::2])])


def test_compressed_recordings_use_the_recorded_topic(tmp_path):
    raw, _, _ = recorded_frames(tmp_path, "ros1")
    jpeg, result, _ = recorded_frames(tmp_path, "ros2", "jpeg")
    assert result["image_topic"] == "/F1ROS/cameraL/image_raw/compressed"
    np.testing.assert_array_equal(jpeg.labels, raw.labels)
    assert np.abs(jpeg.frames.astype(int) - raw.frames).mean() < 4
