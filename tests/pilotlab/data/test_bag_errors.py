"""Every way a bag can be unusable ends in one BagError naming the bag (and topic) and the fix."""
import shutil

import pytest

from pilotlab.data.bags import Topics, read_bag, read_frames
from pilotlab.data.preprocess import PreprocessConfig
from pilotlab.errors import BagError
from tests.pilotlab.data.bagfiles import RawBag, drive_bag, images

CONFIG = PreprocessConfig()
REPAIR = ("it is truncated or corrupt. Record it again, or repair it (`rosbag reindex` for ROS1, "
          "`ros2 bag reindex` for ROS2) and retry")
TOPICS = ("/F1ROS/cameraL/image_raw (sensor_msgs/msg/Image, 3 messages), "
          "/F1ROS/cmd_vel (geometry_msgs/msg/Twist, 3 messages)")


def message(path, **kwargs) -> str:
    with pytest.raises(BagError) as caught:
        read_frames(path, CONFIG, **kwargs)
    return str(caught.value)


def truncate(file):
    data = file.read_bytes()
    file.write_bytes(data[:len(data) // 2])


def test_truncated_ros1_bag(tmp_path):
    """(rosbags' own words held a Python tuple: "('Header could not be read from file.',)": outside test)"""
    drive_bag(tmp_path / "run.bag", "ros1", images(3))
    truncate(tmp_path / "run.bag")
    assert message(tmp_path / "run.bag") == (
        f"{tmp_path}/run.bag: cannot read the bag (Bag index looks damaged: "
        f"Header could not be read from file.); {REPAIR}")


def test_truncated_ros2_sqlite3_bag(tmp_path):
    drive_bag(tmp_path / "run", "sqlite3", images(3))
    truncate(tmp_path / "run" / "run.db3")
    assert message(tmp_path / "run") == (
        f"{tmp_path}/run: cannot read the bag (Cannot open database {tmp_path}/run/run.db3: "
        f"database disk image is malformed); {REPAIR}")


def test_truncated_ros2_mcap_bag(tmp_path):
    drive_bag(tmp_path / "run", "mcap", images(3))
    truncate(tmp_path / "run" / "run.mcap")
    assert message(tmp_path / "run") == f"{tmp_path}/run: cannot read the bag (File end magic is invalid.); {REPAIR}"


def test_a_file_that_is_no_bag_at_all(tmp_path):
    (tmp_path / "noise.bag").write_bytes(b"not a bag" * 50)
    assert message(tmp_path / "noise.bag") == (
        f"{tmp_path}/noise.bag: cannot read the bag (File magic is invalid.); {REPAIR}")


def test_a_corrupt_message_inside_an_intact_bag(tmp_path):
    with RawBag(tmp_path / "short.bag", "ros1") as bag:
        bag.twist(1, 1.0, 0.0)
        image = images(1)[0]
        msg = bag.store.types["sensor_msgs/msg/Image"](header=bag.header(2), height=60, width=80, encoding="rgb8",
                                                       is_bigendian=0, step=240, data=image.reshape(-1)[:1000])
        bag.write("/F1ROS/cameraL/image_raw", "sensor_msgs/msg/Image", 2, msg)
    assert message(tmp_path / "short.bag") == (
        f"{tmp_path}/short.bag, topic /F1ROS/cameraL/image_raw: an image message is inconsistent (80×60 rgb8, "
        "step 240, 1000 bytes of data); the bag is corrupt, record it again")


def test_missing_image_topic_lists_the_topics_present(tmp_path):
    drive_bag(tmp_path / "run.bag", "ros1", images(3))
    assert message(tmp_path / "run.bag", topics=Topics(image="/camera/image")) == (
        f"{tmp_path}/run.bag: the bag has no topic '/camera/image'; topics present: {TOPICS}; "
        "set the image topic to one of them"
        " (a recipe's dataset: topics: {image: NAME}; the command line: --image-topic)")


def test_missing_command_topic_lists_the_topics_present(tmp_path):
    drive_bag(tmp_path / "run", "mcap", images(3))
    assert message(tmp_path / "run", topics=Topics(command="/cmd")) == (
        f"{tmp_path}/run: the bag has no topic '/cmd'; topics present: {TOPICS}; set the command topic to one of them"
        " (a recipe's dataset: topics: {command: NAME}; the command line: --command-topic)")


def test_no_default_image_topic(tmp_path):
    with RawBag(tmp_path / "other.bag", "ros1") as bag:
        bag.twist(1, 1.0, 0.0)
        bag.image(2, images(1)[0], topic="/front/image")
    assert message(tmp_path / "other.bag") == (
        f"{tmp_path}/other.bag: the bag has none of the default image topics (/F1ROS/cameraL/image_raw, "
        "/F1ROS/cameraL/image_raw/compressed); topics present: /F1ROS/cmd_vel (geometry_msgs/msg/Twist, 1 message), "
        "/front/image (sensor_msgs/msg/Image, 1 message); set the image topic to one of them"
        " (a recipe's dataset: topics: {image: NAME}; the command line: --image-topic)")


def test_command_topic_of_the_wrong_type(tmp_path):
    with RawBag(tmp_path / "swap.bag", "ros1") as bag:
        bag.image(1, images(1)[0])
        bag.image(2, images(1)[0], topic="/F1ROS/cmd_vel")
    assert message(tmp_path / "swap.bag") == (
        f"{tmp_path}/swap.bag: topic '/F1ROS/cmd_vel' carries sensor_msgs/msg/Image, not geometry_msgs/msg/Twist "
        "or geometry_msgs/msg/TwistStamped; set the command topic to a topic of that type"
        " (a recipe's dataset: topics: {command: NAME}; the command line: --command-topic) (topics present: "
        "/F1ROS/cameraL/image_raw (sensor_msgs/msg/Image, 1 message), /F1ROS/cmd_vel (sensor_msgs/msg/Image, "
        "1 message))")


@pytest.mark.parametrize("kind", ["ros1", "sqlite3"])
def test_unknown_image_encoding(tmp_path, kind):
    path = tmp_path / ("bayer.bag" if kind == "ros1" else "bayer")
    with RawBag(path, kind) as bag:
        bag.twist(1, 1.0, 0.0)
        bag.image(2, images(1)[0][..., 0].copy(), encoding="bayer_rggb8")
    assert message(path) == (f"{path}, topic /F1ROS/cameraL/image_raw: image encoding 'bayer_rggb8' is not "
                             "supported; use one of rgb8, bgr8, mono8 (or CompressedImage jpeg/png)")


def test_unknown_compressed_format(tmp_path):
    with RawBag(tmp_path / "tiff.bag", "ros1") as bag:
        bag.twist(1, 1.0, 0.0)
        bag.compressed(2, images(1)[0], fmt="tiff")
    assert message(tmp_path / "tiff.bag") == (
        f"{tmp_path}/tiff.bag, topic /F1ROS/cameraL/image_raw/compressed: compressed image format 'tiff' is not "
        "supported; use jpeg or png (or a raw Image in rgb8, bgr8, mono8)")


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_empty_bag(tmp_path, kind):
    path = tmp_path / ("empty.bag" if kind == "ros1" else "empty")
    with RawBag(path, kind):
        pass
    assert message(path) == (f"{path}: the bag is empty (no messages); record it again, "
                             "or check that the recorder wrote to this path")


def test_no_image_after_the_first_command(tmp_path):
    with RawBag(tmp_path / "late.bag", "ros1") as bag:
        bag.image(1, images(1)[0])
        bag.twist(5, 1.0, 0.0)
    assert message(tmp_path / "late.bag") == (
        f"{tmp_path}/late.bag: no image on '/F1ROS/cameraL/image_raw' at or after the first command on "
        "'/F1ROS/cmd_vel'; the recording has no labelled frames, record it again")


def test_commands_stamped_long_before_every_image_are_refused_and_a_gap_is_said(tmp_path):
    """Outside test: commands stamped 1000 s before the images labelled every frame with the last one,
    silently (a constant label to train on). Now an error; a stream that stops for a while is said."""
    frames = images(30)
    with RawBag(tmp_path / "apart.bag", "ros1") as bag:
        for i, rgb in enumerate(frames):
            bag.twist(10**9 + i * 10**8, 1.0, 0.1 * i)
            bag.image(1001 * 10**9 + i * 10**8, rgb)
    assert message(tmp_path / "apart.bag") == (
        f"{tmp_path}/apart.bag: every image on '/F1ROS/cameraL/image_raw' comes 997.1 s or more after the last "
        "command on '/F1ROS/cmd_vel' before it, so every frame would be labelled by a stale command; the commands "
        "are stamped by another clock or recorded apart from the images: give the bag whose commands drive these "
        "images")
    with RawBag(tmp_path / "gap.bag", "ros1") as bag:   # commands stop after 1 s; images go on 2 s more
        for i, rgb in enumerate(frames):
            stamp = 10**9 + i * 10**8
            if i < 10:
                bag.twist(stamp - 10**6, 1.0, 0.0)
            bag.image(stamp, rgb)
    read = read_frames(tmp_path / "gap.bag", CONFIG)
    assert len(read) == 30 and read.meta["stale_commands"] == {"frames": 11, "max_age_s": 2.001, "limit_s": 1.0}
    drive_bag(tmp_path / "ok.bag", "ros1", images(3))
    assert "stale_commands" not in read_frames(tmp_path / "ok.bag", CONFIG).meta


def test_paths_that_are_not_bags(tmp_path):
    assert message(tmp_path / "missing.bag") == (
        f"{tmp_path}/missing.bag: no such bag; check the path (a ROS1 .bag file or a ROS2 bag folder)")
    (tmp_path / "folder").mkdir()
    assert message(tmp_path / "folder") == (
        f"{tmp_path}/folder: this folder is not a ROS2 bag (it has no metadata.yaml) nor a dataset folder "
        "(no data.csv); if its recording was interrupted, run `ros2 bag reindex` on it")
    (tmp_path / "notes.txt").write_text("hello")
    assert message(tmp_path / "notes.txt") == (
        f"{tmp_path}/notes.txt: not a bag file; a ROS1 bag ends in .bag, a ROS2 bag is a folder "
        "(or its .db3 / .mcap file)")


def test_a_bad_bag_breaks_nothing_else(tmp_path):
    drive_bag(tmp_path / "good.bag", "ros1", images(3))
    shutil.copy(tmp_path / "good.bag", tmp_path / "bad.bag")
    truncate(tmp_path / "bad.bag")
    with pytest.raises(BagError):
        read_bag(tmp_path / "bad.bag", CONFIG)
    assert len(read_bag(tmp_path / "good.bag", CONFIG)) == 3


def test_a_bag_folder_holding_a_link_to_a_system_file_is_refused(tmp_path, capsys):
    """Read directly (`dataset inspect`, no hashing first), the rule holds for each file, links resolved."""
    from pilotlab.cli import main
    drive_bag(tmp_path / "run", "sqlite3", images(3))
    (tmp_path / "run" / "run.db3").unlink()
    (tmp_path / "run" / "run.db3").symlink_to("/proc/self/environ")
    assert message(tmp_path / "run").startswith(f"{tmp_path}/run: {tmp_path}/run/run.db3 is a link to /proc/")
    assert main(["dataset", "inspect", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "a system file (below /proc), not data" in err and len(err.strip().splitlines()) == 1
