"""The sqlite3 fast path reads exactly what the general (rosbags) path reads."""
import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from pilotlab.data import sqlite_images
from pilotlab.data.bags import read_bag
from pilotlab.data.preprocess import PreprocessConfig
from tests.pilotlab.data.bagfiles import RawBag, drive_bag, images

CONFIG = PreprocessConfig(crop_top=0.3, crop_bottom=0.9)


def both_paths(path, monkeypatch, config=CONFIG):
    fast = read_bag(path, config)
    with monkeypatch.context() as patch:
        patch.setattr(sqlite_images, "applies", lambda *args: None)
        general = read_bag(path, config)
    return fast, general


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "mono8"])
def test_fast_path_equals_the_general_path(tmp_path, monkeypatch, encoding):
    drive_bag(tmp_path / "run", "sqlite3", images(5, 90, 120), encoding=encoding, first_command=1)
    fast, general = both_paths(tmp_path / "run", monkeypatch)
    np.testing.assert_array_equal(fast.frames, general.frames)
    np.testing.assert_array_equal(fast.labels, general.labels)
    assert fast.meta == general.meta and fast.meta["encoding"] == encoding


def test_padded_rows_and_a_long_frame_id(tmp_path, monkeypatch):
    store = get_typestore(Stores.ROS2_HUMBLE)
    frame = images(1, 90, 120)[0]
    padded = np.zeros((90, 120 * 3 + 8), np.uint8)
    padded[:, :360] = frame.reshape(90, 360)
    with RawBag(tmp_path / "odd", "sqlite3") as bag:
        bag.twist(1, 1.0, 0.5)
        header = store.types["std_msgs/msg/Header"](stamp=store.types["builtin_interfaces/msg/Time"](sec=0, nanosec=2),
                                                    frame_id="camera_" * 60)
        msg = store.types["sensor_msgs/msg/Image"](header=header, height=90, width=120, encoding="rgb8",
                                                   is_bigendian=0, step=368, data=padded.reshape(-1))
        bag.write("/F1ROS/cameraL/image_raw", "sensor_msgs/msg/Image", 2, msg)
        raw = store.serialize_cdr(msg, "sensor_msgs/msg/Image")
    header = sqlite_images.parse_header(raw)
    assert (header.height, header.width, header.encoding, header.step) == (90, 120, "rgb8", 368)
    assert raw[header.data_offset:header.data_offset + 368 * 90] == padded.tobytes()
    fast, general = both_paths(tmp_path / "odd", monkeypatch)
    np.testing.assert_array_equal(fast.frames, general.frames)


def test_it_applies_only_to_one_uncompressed_database_of_raw_images(tmp_path):
    from pilotlab.data.bags import open_bag
    drive_bag(tmp_path / "raw", "sqlite3", images(2))
    drive_bag(tmp_path / "png", "sqlite3", images(2), encoding="png")
    drive_bag(tmp_path / "mcap", "mcap", images(2))
    with open_bag(tmp_path / "raw") as reader:
        assert sqlite_images.applies(tmp_path / "raw", reader, "sensor_msgs/msg/Image") == tmp_path / "raw" / "raw.db3"
    with open_bag(tmp_path / "png") as reader:
        assert sqlite_images.applies(tmp_path / "png", reader, "sensor_msgs/msg/CompressedImage") is None
    with open_bag(tmp_path / "mcap") as reader:
        assert sqlite_images.applies(tmp_path / "mcap", reader, "sensor_msgs/msg/Image") is None
