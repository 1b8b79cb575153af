"""`pilotlab dataset inspect` and `pilotlab dataset convert`, through the real command line."""
import json
import sqlite3

import pytest

from pilotlab.cli import main
from tests.pilotlab.data.bagfiles import RawBag, drive_bag, images
from tests.pilotlab.data.test_folder import make_folder


def test_inspect_json_lists_topics_sizes_and_ranges(tmp_path, capsys):
    drive_bag(tmp_path / "run", "mcap", images(5))
    assert main(["dataset", "inspect", str(tmp_path / "run"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "ros2-mcap" and info["messages"] == 10
    assert [(t["name"], t["type"], t["count"]) for t in info["topics"]] == [
        ("/F1ROS/cameraL/image_raw", "sensor_msgs/msg/Image", 5), ("/F1ROS/cmd_vel", "geometry_msgs/msg/Twist", 5)]
    assert info["images"] == {"/F1ROS/cameraL/image_raw": {"type": "sensor_msgs/msg/Image", "encoding": "rgb8",
                                                         "size": [60, 80]}}
    assert info["commands"]["v"] == [1.0, 1.399999976158142] and info["commands"]["w"][0] == -0.30000001192092896
    assert info["duration_s"] == 0.401
    # 5 frames at 10 Hz: 4 intervals (the outside test's 3 frames at 20 Hz read 30 Hz, count over duration)
    assert [round(t["rate_hz"]) for t in info["topics"]] == [10, 10]


def test_inspect_table_for_people(tmp_path, capsys):
    with RawBag(tmp_path / "c.bag", "ros1") as bag:
        bag.twist(10**9, 2.0, 0.5)
        bag.compressed(10**9 + 1, images(1)[0], "jpeg")
    assert main(["dataset", "inspect", str(tmp_path / "c.bag")]) == 0
    out = capsys.readouterr().out
    assert "/F1ROS/cameraL/image_raw/compressed" in out and "80×60 jpeg" in out
    assert "v 2.000 .. 2.000 m/s, w 0.500 .. 0.500 rad/s" in out


def test_inspect_a_bad_bag_prints_one_line_and_fails(tmp_path, capsys):
    (tmp_path / "bad.bag").write_bytes(b"nope")
    assert main(["dataset", "inspect", str(tmp_path / "bad.bag")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"pilotlab: error: {tmp_path}/bad.bag: cannot read the bag") and err.count("\n") == 1


def test_inspect_says_which_image_topic_the_frames_job_could_not_decode(tmp_path, capsys):
    """Outside test: inspect showed "640×480 rgba8" and exited 0 for a bag whose frames job then failed
    ("image encoding 'rgba8' is not supported"); and the frames job's message named --image-topic, an
    option no command that reads bags had."""
    with RawBag(tmp_path / "c.bag", "ros1") as bag:
        bag.twist(10**9, 2.0, 0.5)
        bag.image(10**9 + 1, images(1)[0], encoding="rgba8", topic="/depth")
        bag.image(10**9 + 2, images(1)[0], topic="/camera/image_raw")
    assert main(["dataset", "inspect", str(tmp_path / "c.bag")]) == 0      # one image topic frames can read
    out = capsys.readouterr().out
    assert "cannot be read:" in out and "'rgba8' is not" in out
    assert main(["dataset", "inspect", str(tmp_path / "c.bag"), "--image-topic", "/depth"]) == 1
    capsys.readouterr()
    assert main(["dataset", "inspect", str(tmp_path / "c.bag"), "--image-topic", "/camera/image_raw", "--json"]) == 0
    assert list(json.loads(capsys.readouterr().out)["images"]) == ["/camera/image_raw"]
    assert main(["dataset", "inspect", str(tmp_path / "c.bag"), "--image-topic", "/nope"]) == 2
    assert "the bag has no topic '/nope'" in capsys.readouterr().err
    # outside test: a wrong --command-topic printed "no commands" and exited 0 (a wrong --image-topic was an error)
    assert main(["dataset", "inspect", str(tmp_path / "c.bag"), "--command-topic", "/F1ROS/cmd_vell"]) == 2
    err = capsys.readouterr().err
    assert "the bag has no topic '/F1ROS/cmd_vell'; topics present: " in err and err.count("\n") == 1
    assert main(["dataset", "inspect", str(tmp_path / "c.bag"), "--command-topic", "/depth"]) == 2
    assert "topic '/depth' carries sensor_msgs/msg/Image, not geometry_msgs/msg/Twist" in capsys.readouterr().err
    assert main(["dataset", "inspect", str(tmp_path / "c.bag"), "--command-topic", "/F1ROS/cmd_vel"]) == 0


def test_inspect_fails_with_a_word_where_the_frames_job_would_find_no_images_or_no_commands(tmp_path, capsys):
    """Outside test: a bag without commands printed "no commands" and exited 0; one without images exited 1
    without a word (`all` over no image topics)."""
    with RawBag(tmp_path / "nocmd.bag", "ros1") as bag:
        bag.image(10**9, images(1)[0])
    assert main(["dataset", "inspect", str(tmp_path / "nocmd.bag")]) == 1
    assert "no commands: the bag has no /F1ROS/cmd_vel" in capsys.readouterr().out
    with RawBag(tmp_path / "noimg.bag", "ros1") as bag:
        bag.twist(10**9, 2.0, 0.5)
    assert main(["dataset", "inspect", str(tmp_path / "noimg.bag")]) == 1
    assert "no images: the bag has no topic of type sensor_msgs/Image or CompressedImage" in capsys.readouterr().out


@pytest.mark.parametrize("kind, damage", [("sqlite3", "no messages"), ("mcap", "type changed")])
def test_inspect_an_image_topic_announced_but_not_readable_is_one_line(tmp_path, capsys, kind, damage):
    path = tmp_path / "run"
    drive_bag(path, kind, images(5))
    if damage == "no messages":
        with sqlite3.connect(next(path.glob("*.db3"))) as db:
            db.execute("DELETE FROM messages WHERE topic_id = "
                       "(SELECT id FROM topics WHERE name = '/F1ROS/cameraL/image_raw')")
    else:  # metadata.yaml says the camera topic is compressed; the data says otherwise
        metadata = path / "metadata.yaml"
        metadata.write_text(metadata.read_text().replace("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"))
    assert main(["dataset", "inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert "topic '/F1ROS/cameraL/image_raw' is announced with 5" in err and "none can be read" in err
    assert len(err.strip().splitlines()) == 1


def test_convert_a_folder_then_inspect_it(tmp_path, capsys):
    folder = make_folder(tmp_path / "dls", images(4))
    assert main(["dataset", "convert", str(folder), "--out", str(tmp_path / "out.bag")]) == 0
    assert "wrote 4 frames" in capsys.readouterr().out
    assert main(["dataset", "inspect", str(tmp_path / "out.bag"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "ros1" and info["commands"]["count"] == 4
    assert main(["dataset", "inspect", str(folder), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["format"] == "folder"


def test_inspect_a_folder_opens_every_image_it_names(tmp_path, capsys):
    import cv2
    import numpy as np
    folder = make_folder(tmp_path / "dls", images(5))
    cv2.imwrite(str(folder / "3.png"), np.zeros((30, 40, 3), np.uint8))   # another camera's size
    (folder / "4.png").write_bytes(b"not an image")
    assert main(["dataset", "inspect", str(folder)]) == 1   # the frames job would stop at 4.png
    out = capsys.readouterr().out
    assert "png of 2 sizes: 80×60 (3), 40×30 (1)" in out
    assert "1 image(s) named in data.csv cannot be read (first: 4.png)" in " ".join(out.split())
    assert main(["dataset", "inspect", str(folder), "--json"]) == 1
    image = json.loads(capsys.readouterr().out)["images"]["data.csv"]
    assert image["sizes"] == {"80x60": 3, "40x30": 1} and image["unreadable_first"] == ["4.png"]


def test_convert_to_ros2_mcap_with_compressed_images(tmp_path, capsys):
    folder = make_folder(tmp_path / "dls", images(2))
    assert main(["dataset", "convert", str(folder), "--out", str(tmp_path / "ros2"), "--storage", "mcap",
                 "--compression", "png"]) == 0
    capsys.readouterr()
    main(["dataset", "inspect", str(tmp_path / "ros2"), "--json"])
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "ros2-mcap"
    assert info["images"]["/F1ROS/cameraL/image_raw/compressed"]["encoding"] == "rgb8; png compressed bgr8"


@pytest.mark.parametrize("topics, message", [
    (["--image-topic", "/same", "--command-topic", "/same"], "the image and command topics are both '/same'"),
    (["--image-topic", ""], "the image topic '' is not a ROS topic name"),
    (["--command-topic", "not a topic"], "the command topic 'not a topic' is not a ROS topic name"),
])
def test_convert_refuses_topics_no_reader_could_use(tmp_path, capsys, topics, message):
    """Outside test: one topic for images and commands wrote a bag no reader could use, and an empty
    --image-topic silently meant the default; both exited 0."""
    folder = make_folder(tmp_path / "dls", images(2))
    assert main(["dataset", "convert", str(folder), "--out", str(tmp_path / "out"), *topics]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "out").exists()
