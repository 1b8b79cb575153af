"""Reading real bags (ROS1, ROS2 sqlite3 and mcap) written with rosbags."""
import numpy as np
import pytest

from pilotlab.data.bags import Topics, read_bag, read_frames
from pilotlab.data.preprocess import PreprocessConfig, preprocess
from tests.pilotlab.data.bagfiles import KINDS, RawBag, bag_path, drive_bag, images

CONFIG = PreprocessConfig()


def expected(frames, index):
    return np.stack([preprocess(frames[i], CONFIG) for i in index])


@pytest.mark.parametrize("kind", KINDS)
def test_reads_frames_and_the_command_in_force(tmp_path, kind):
    frames = images(8)
    labels, index = drive_bag(bag_path(tmp_path, kind), kind, frames)
    data = read_bag(bag_path(tmp_path, kind), CONFIG)
    assert data.frames.shape == (8, 66, 200, 3) and data.frames.dtype == np.uint8
    np.testing.assert_array_equal(data.frames, expected(frames, index))
    np.testing.assert_array_equal(data.labels, labels)
    assert data.meta["format"] == {"ros1": "ros1", "sqlite3": "ros2-sqlite3", "mcap": "ros2-mcap"}[kind]
    assert data.meta["image_size"] == [60, 80] and data.meta["encoding"] == "rgb8"
    assert list(data.recording) == [0] * 8


def test_the_same_frames_in_ros1_and_ros2_read_back_identically(tmp_path):
    frames = images(6)
    sets = []
    for kind in KINDS:
        drive_bag(bag_path(tmp_path, kind), kind, frames, first_command=2)
        sets.append(read_bag(bag_path(tmp_path, kind), CONFIG))
    for other in sets[1:]:
        np.testing.assert_array_equal(other.frames, sets[0].frames)
        np.testing.assert_array_equal(other.labels, sets[0].labels)
        assert other.meta["start_ns"] == sets[0].meta["start_ns"]


def test_frames_before_the_first_command_are_dropped(tmp_path):
    frames = images(7)
    labels, index = drive_bag(tmp_path / "late.bag", "ros1", frames, first_command=3)
    data = read_bag(tmp_path / "late.bag", CONFIG)
    assert len(data) == 4 and data.meta["dropped"] == 3
    np.testing.assert_array_equal(data.frames, expected(frames, index))
    np.testing.assert_array_equal(data.labels, labels)


def test_each_image_gets_the_latest_command_at_or_before_it(tmp_path):
    frames = images(4)
    with RawBag(tmp_path / "irregular.bag", "ros1") as bag:
        bag.twist(100, 1.0, 0.1)
        bag.image(100, frames[0])           # same stamp: this command is in force
        bag.twist(150, 2.0, 0.2)
        bag.twist(180, 3.0, 0.3)
        bag.image(200, frames[1])           # two commands since: the later one
        bag.image(300, frames[2])           # none since: still the last one
        bag.twist(301, 4.0, 0.4)
        bag.image(400, frames[3])
    data = read_bag(tmp_path / "irregular.bag", CONFIG)
    np.testing.assert_allclose(data.labels, [[1, 0.1], [3, 0.3], [3, 0.3], [4, 0.4]], rtol=1e-6)


@pytest.mark.parametrize("encoding", ["bgr8", "mono8", "png"])
def test_other_encodings_give_the_frames_of_the_rgb_image(tmp_path, encoding):
    frames = images(3)
    if encoding == "mono8":  # a grey camera: its RGB equivalent has three equal channels
        frames = [np.repeat(f[..., :1], 3, axis=2) for f in frames]
    drive_bag(tmp_path / "enc.bag", "ros1", frames, encoding=encoding)
    data = read_bag(tmp_path / "enc.bag", CONFIG)
    np.testing.assert_array_equal(data.frames, expected(frames, range(3)))
    assert data.meta["encoding"] == encoding


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_jpeg_images_decode_close_to_the_original(tmp_path, kind):
    frames = images(3)
    drive_bag(bag_path(tmp_path, kind), kind, frames, encoding="jpeg")
    data = read_bag(bag_path(tmp_path, kind), CONFIG)
    assert data.meta["image_topic"] == "/F1ROS/cameraL/image_raw/compressed"  # the default's fallback
    error = np.abs(data.frames.astype(int) - expected(frames, range(3)))
    assert error.mean() < 3


def test_topics_named_by_the_caller_and_twist_stamped(tmp_path):
    frames = images(3)
    with RawBag(tmp_path / "named", "sqlite3") as bag:
        for i, rgb in enumerate(frames):
            bag.twist_stamped(i * 10, 1.0 + i, -0.5 * i, topic="/car/cmd")
            bag.image(i * 10 + 1, rgb, topic="/car/camera")
            bag.image(i * 10 + 1, rgb[::-1].copy())  # a default-named topic that must be ignored
    data = read_bag(tmp_path / "named", CONFIG, Topics(image="/car/camera", command="/car/cmd"))
    np.testing.assert_array_equal(data.frames, expected(frames, range(3)))
    np.testing.assert_allclose(data.labels[:, 1], [0, -0.5, -1.0])


@pytest.mark.parametrize("workers", [0, 1, 2])
def test_worker_threads_give_the_same_frames(tmp_path, workers):
    frames = images(70)  # more than two chunks
    drive_bag(tmp_path / "many.bag", "ros1", frames)
    data = read_bag(tmp_path / "many.bag", CONFIG, workers=workers)
    np.testing.assert_array_equal(data.frames, expected(frames, range(70)))


def test_progress_is_reported(tmp_path):
    drive_bag(tmp_path / "p.bag", "ros1", images(40))
    calls = []
    read_frames(tmp_path / "p.bag", CONFIG, progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (40, 40) and len(calls) >= 2


def test_a_ros2_storage_file_can_be_named_directly(tmp_path):
    frames = images(3)
    drive_bag(tmp_path / "direct", "mcap", frames)
    (mcap,) = (tmp_path / "direct").glob("*.mcap")
    np.testing.assert_array_equal(read_bag(mcap, CONFIG).frames, expected(frames, range(3)))
