"""Damaged bags: a damaged message is left out and reported (count, topic, time); a recording that
lost more than 2 % of a topic is refused; random damage never gives a traceback or a NaN label."""
import random
import sqlite3

import numpy as np
import pytest

from matrix.errors import MatrixError
from pilotlab.data.bags import read_frames
from pilotlab.data.preprocess import PreprocessConfig
from pilotlab.errors import BagError
from tests.pilotlab.data.bagfiles import KINDS, RawBag, bag_path, drive_bag, images

CONFIG = PreprocessConfig()
FRAMES = 60


def recording(path, kind, damaged_images=(), damaged_commands=(), n=FRAMES):
    """A bag of `n` frames and commands; the listed images have a header that no longer matches their
    data (as a flipped byte in `step` leaves it), the listed commands a NaN (flipped exponent bits)."""
    with RawBag(path, kind) as bag:
        for i, rgb in enumerate(images(n)):
            stamp = 10**9 + i * 10**8
            bag.twist(stamp - 10**6, float("nan") if i in damaged_commands else 1.0, 0.1)
            if i in damaged_images:
                msg = bag.store.types["sensor_msgs/msg/Image"](
                    header=bag.header(stamp), height=60, width=80, encoding="rgb8", is_bigendian=0,
                    step=2400, data=rgb.reshape(-1))
                bag.write("/F1ROS/cameraL/image_raw", "sensor_msgs/msg/Image", stamp, msg)
            else:
                bag.image(stamp, rgb)
    return path


@pytest.mark.parametrize("kind", KINDS)
def test_one_damaged_image_and_command_are_left_out_and_reported(tmp_path, kind):
    path = recording(bag_path(tmp_path, kind), kind, damaged_images={30}, damaged_commands={10})
    frames = read_frames(path, CONFIG)
    assert len(frames) == FRAMES - 1 and np.isfinite(frames.labels).all()
    image, command = frames.meta["damaged"]
    assert image["topic"] == "/F1ROS/cameraL/image_raw" and image["count"] == 1 and image["times_s"] == [4.0]
    assert "an image message is inconsistent (80×60 rgb8, step 2400" in image["reason"]
    assert command == {"topic": "/F1ROS/cmd_vel", "count": 1, "missing": 0, "times_s": [1.999],
                       "reason": "a command is damaged (v = nan is not a command)"}


@pytest.mark.parametrize("kind", KINDS)
def test_more_than_two_percent_lost_is_an_error(tmp_path, kind):
    path = recording(bag_path(tmp_path, kind), kind, damaged_images={3, 20, 40})
    with pytest.raises(BagError, match=r"topic /F1ROS/cameraL/image_raw: 3 of 60 messages are damaged or missing \(3 damaged at "
                                       r"t=1.300, 3.000, 5.000 s \(first: an image message is inconsistent"):
        read_frames(path, CONFIG)
    path = recording(bag_path(tmp_path, kind, "nan"), kind, damaged_commands={3, 20})
    with pytest.raises(BagError, match=r"topic /F1ROS/cmd_vel: 2 of 60 messages are damaged or missing .*v = nan is not "
                                       r"a command.*: record it again, or mend those messages$"):   # (no reindex: outside test)
        read_frames(path, CONFIG)


def test_every_command_damaged_names_the_bag_and_topic(tmp_path):
    path = recording(bag_path(tmp_path, "mcap"), "mcap", damaged_commands=set(range(10)), n=10)
    with pytest.raises(BagError) as caught:
        read_frames(path, CONFIG)
    assert str(caught.value) == f"{path}, topic /F1ROS/cmd_vel: a command is damaged (v = nan is not a command)"


@pytest.mark.parametrize("kind", ["sqlite3", "mcap"])
def test_a_false_message_count_is_reported(tmp_path, kind):
    path = bag_path(tmp_path, kind)
    drive_bag(path, kind, images(20))
    metadata = path / "metadata.yaml"
    metadata.write_text(metadata.read_text().replace("message_count: 20", "message_count: 25", 1))
    with pytest.raises(BagError, match=r"5 of 25 messages are damaged or missing \(5 announced by the bag's index but missing\)"):
        read_frames(path, CONFIG)


def test_flipped_bytes_in_a_sqlite_message_header(tmp_path):
    path = bag_path(tmp_path, "sqlite3")
    drive_bag(path, "sqlite3", images(FRAMES))
    with sqlite3.connect(next(path.glob("*.db3"))) as db:
        rowid, data = db.execute("SELECT m.id, m.data FROM messages m JOIN topics t ON m.topic_id = t.id "
                                 "WHERE t.name = '/F1ROS/cameraL/image_raw' ORDER BY m.timestamp LIMIT 1 OFFSET 7").fetchone()
        data = bytearray(data)
        data[4 + 8 + 4 + 4] ^= 0x40      # the image's height: 60 -> 124 rows, more than its data holds
        db.execute("UPDATE messages SET data = ? WHERE id = ?", (bytes(data), rowid))
    frames = read_frames(path, CONFIG)
    assert len(frames) == FRAMES - 1 and frames.meta["damaged"][0]["times_s"] == [1.7]


def damage_file(path, how: str, seed: int) -> None:
    file = path if path.is_file() else next(f for f in path.iterdir() if f.suffix in (".db3", ".mcap"))
    data, rng = bytearray(file.read_bytes()), random.Random(seed)
    if how == "cut":
        data = data[:-1 - rng.randrange(64)]
    else:
        for _ in range(rng.choice([1, 10, 100])):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    file.write_bytes(bytes(data))


def random_damage_cases(count: int) -> list[tuple[str, str, int]]:
    return [(KINDS[i % 3], "cut" if i % 5 == 4 else "flip", i) for i in range(count)]


def check_random_damage(tmp_path, kind: str, how: str, seed: int, encoding: str = "rgb8") -> str:
    path = bag_path(tmp_path, kind, f"run{seed}")
    drive_bag(path, kind, images(20), encoding=encoding)
    damage_file(path, how, seed)
    try:
        frames = read_frames(path, CONFIG)
    except MatrixError as error:
        assert "\n" not in str(error)
        return "refused"
    assert np.isfinite(frames.labels).all() and len(frames) >= 19
    return "read"


@pytest.mark.parametrize("kind, how, seed", random_damage_cases(12))
def test_random_damage_is_read_or_refused_never_a_traceback(tmp_path, kind, how, seed):
    check_random_damage(tmp_path, kind, how, seed, encoding="png" if seed % 2 else "rgb8")


@pytest.mark.slow
def test_many_randomly_damaged_bags(tmp_path):
    outcomes = [check_random_damage(tmp_path, kind, how, seed, encoding="png" if seed % 2 else "rgb8")
                for kind, how, seed in random_damage_cases(240)]
    print({o: outcomes.count(o) for o in set(outcomes)})


def test_the_frames_job_reports_what_it_left_out(tmp_path):
    from matrix.kinds import KINDS
    from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
    from tests.pilotlab.jobs.context import context
    path = recording(bag_path(tmp_path, "mcap"), "mcap", damaged_images={30})
    result = KINDS.get("frames").handler(context(tmp_path, "frames", "frames", inputs={"bag": path}))
    assert result["frames"] == FRAMES - 1 and result["damaged"][0]["times_s"] == [4.0]
