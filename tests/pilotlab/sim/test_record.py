import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pydantic
import pytest
from rosbags.highlevel import AnyReader

from pilotlab.circuits import CIRCUITS
from pilotlab.circuits.load import get_circuit
from pilotlab.cli import main
from pilotlab.errors import PilotlabError
from pilotlab.data.topics import COMMAND_TOPIC as CMD_TOPIC
from pilotlab.data.topics import COMPRESSED_IMAGE_TOPIC as COMPRESSED_TOPIC
from pilotlab.data.topics import IMAGE_TOPIC, METADATA_TOPIC
from pilotlab.data.topics import ODOMETRY_TOPIC as ODOM_TOPIC
from pilotlab.sim.record import RecordSpec, record
from tests.child import python_path

ROOT = Path(__file__).resolve().parents[3]


def read_bag(path):
    """{topic: [(bag time ns, message)]} of a ROS1 or ROS2 bag."""
    messages = {}
    with AnyReader([Path(path)]) as reader:
        for connection, timestamp, raw in reader.messages():
            messages.setdefault(connection.topic, []).append((timestamp, reader.deserialize(raw, connection.msgtype)))
    return messages


def stamp_ns(message):
    return message.header.stamp.sec * 10**9 + message.header.stamp.nanosec


@pytest.mark.parametrize("format", ["ros1", "ros2"])
def test_a_recorded_bag_has_the_configured_messages(stadium_csv, tmp_path, format):
    spec = RecordSpec(circuit=stadium_csv, direction="ccw", laps=0.2, seed=5, camera={"width": 64, "height": 48}, rate_hz=5,
                      format=format)
    summary = record(spec, tmp_path / "run")
    assert summary.path == str(tmp_path / ("run.bag" if format == "ros1" else "run"))
    assert summary.termination == "lap_completed" and not summary.interrupted
    messages = read_bag(summary.path)
    assert set(messages) == {IMAGE_TOPIC, CMD_TOPIC, ODOM_TOPIC, METADATA_TOPIC}
    images, commands, odometry = messages[IMAGE_TOPIC], messages[CMD_TOPIC], messages[ODOM_TOPIC]
    assert len(commands) == len(odometry) == summary.commands
    assert len(images) == summary.frames == -(-summary.commands // 4)  # 20 Hz commands, 5 Hz frames
    # Stamped in simulated time: commands every 50 ms from 0, frames every 200 ms, header = bag time.
    assert [t for t, _ in commands] == [i * 50_000_000 for i in range(len(commands))]
    assert [t for t, _ in images] == [i * 200_000_000 for i in range(len(images))]
    assert all(stamp_ns(m) == t for t, m in images + odometry)
    image = images[3][1]
    assert (image.width, image.height, image.encoding, image.step) == (64, 48, "rgb8", 192)
    frame = image.data.reshape(48, 64, 3)
    assert np.any(np.all(frame == (205, 30, 30), axis=2))  # the red line is in the picture
    v, w = commands[-1][1].linear.x, commands[-1][1].angular.z
    assert 3.0 < v < 14.0 and abs(w) < 3.0
    odom = odometry[-1][1]
    assert odom.header.frame_id == "odom" and odom.child_frame_id == "base_link" and odom.twist.twist.linear.x > 3
    meta = json.loads(messages[METADATA_TOPIC][0][1].data)
    assert (meta["circuit"], meta["direction"], meta["seed"], meta["rate_hz"]) == ("stadium", "ccw", 5, 5)


def test_the_same_seed_gives_identical_messages(stadium_csv, tmp_path):
    spec = RecordSpec(circuit=stadium_csv, laps=0.15, seed=2, camera={"width": 40, "height": 30}, noise=0.3,
                      start="random", format="ros1")
    first, second = record(spec, tmp_path / "a.bag"), record(spec, tmp_path / "b.bag")
    other = record(spec.model_copy(update={"seed": 3}), tmp_path / "c.bag")
    a, b, c = read_bag(first.path), read_bag(second.path), read_bag(other.path)
    for topic in (IMAGE_TOPIC, CMD_TOPIC, ODOM_TOPIC):
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]]
        assert [repr(m) for _, m in a[topic]] == [repr(m) for _, m in b[topic]]
    assert repr(a[ODOM_TOPIC][0][1]) != repr(c[ODOM_TOPIC][0][1])  # another seed, another random start


def test_compressed_images_decode_to_the_frames(stadium_csv, tmp_path):
    raw = record(RecordSpec(circuit=stadium_csv, laps=0.05, camera={"width": 64, "height": 48}, rate_hz=20), tmp_path / "raw")
    png = record(RecordSpec(circuit=stadium_csv, laps=0.05, camera={"width": 64, "height": 48}, rate_hz=20, compressed="png",
                            format="ros2"), tmp_path / "png")
    jpeg = record(RecordSpec(circuit=stadium_csv, laps=0.05, camera={"width": 64, "height": 48}, rate_hz=20, compressed="jpeg"),
                  tmp_path / "jpeg")
    frames = [m.data.reshape(48, 64, 3) for _, m in read_bag(raw.path)[IMAGE_TOPIC]]
    for summary, tolerance in ((png, 0), (jpeg, 40)):
        compressed = read_bag(summary.path)[COMPRESSED_TOPIC]
        assert len(compressed) == len(frames) and IMAGE_TOPIC not in read_bag(summary.path)
        assert compressed[0][1].format.startswith("rgb8; ")
        decoded = cv2.cvtColor(cv2.imdecode(compressed[5][1].data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        assert np.percentile(np.abs(decoded.astype(int) - frames[5]), 99) <= tolerance
    assert png.bytes < raw.bytes


def test_bad_settings_are_refused(stadium_csv, tmp_path):
    with pytest.raises(PilotlabError, match="rate_hz must divide the control rate 20 Hz"):
        record(RecordSpec(circuit=stadium_csv, rate_hz=3), tmp_path / "x")
    with pytest.raises(pydantic.ValidationError, match="Input should be .ros1. or .ros2."):
        RecordSpec(circuit=stadium_csv, format="mcap")
    (tmp_path / "exists.bag").write_text("")
    with pytest.raises(PilotlabError, match="already exists"):
        record(RecordSpec(circuit=stadium_csv, format="ros1"), tmp_path / "exists.bag")


def test_cli_record_writes_a_bag(stadium_csv, tmp_path, capsys):
    status = main(["record", "--circuit", stadium_csv, "--laps", "0.05", "--out", str(tmp_path / "cli"),
                   "--size", "32x24", "--rate", "20", "--format", "ros2"])
    assert status == 0
    assert "frames" in capsys.readouterr().out
    assert len(read_bag(tmp_path / "cli")[IMAGE_TOPIC]) > 5


@pytest.mark.parametrize("stop, code, said", [(signal.SIGINT, 130, "interrupted: the bag holds"),
                                              # outside test: SIGTERM (`timeout`, `kill`) left a bag without its index
                                              (signal.SIGTERM, 143, "terminated (SIGTERM): the bag holds")])
def test_ctrl_c_or_sigterm_leaves_a_valid_readable_bag(tmp_path, stop, code, said):
    out = tmp_path / "interrupted.bag"
    command = [sys.executable, "-m", "pilotlab", "record", "--circuit", "montreal", "--out", str(out),
               "--size", "64x48", "--rate", "20"]
    process = subprocess.Popen(command, cwd=ROOT, env={**os.environ, "PYTHONPATH": python_path(ROOT)},
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 60
    while not (out.exists() and out.stat().st_size > 500_000) and time.time() < deadline:
        time.sleep(0.1)  # until it has recorded for a while (the ROS1 writer flushes 1 MB chunks)
    process.send_signal(stop)
    output, _ = process.communicate(timeout=60)
    assert process.returncode == code, output
    assert said in output
    messages = read_bag(out)
    assert 5 < len(messages[IMAGE_TOPIC]) <= len(messages[CMD_TOPIC])
    assert messages[CMD_TOPIC][-1][0] < 272.8e9  # stopped long before the end of the lap


def record_with_swerves(tmp_path, circuit, direction, seed):
    """A lap recorded with noise 0.1 (tiny frames) and the share of its odometry more than 0.3 m off
    the line, read back from the bag: the recoveries the noise is there for."""
    spec = RecordSpec(circuit=circuit, direction=direction, seed=seed, noise=0.1, camera={"width": 32, "height": 24}, rate_hz=5,
                      format="ros2")
    summary = record(spec, tmp_path / f"{circuit}-{direction}-{seed}")
    track, near, off = get_circuit(circuit, direction), 0.0, []
    for _, message in read_bag(summary.path)[ODOM_TOPIC]:
        projection = track.project(message.pose.pose.position.x, message.pose.pose.position.y, near_s=near)
        near = projection.s
        off.append(projection.distance > 0.3)
    return summary, float(np.mean(off))


def test_swerves_never_take_the_recording_off_the_road(tmp_path):
    """nurburgring cw, seed 2 used to end off_road at 497 m (2.99 m from the line)."""
    summary, off_line = record_with_swerves(tmp_path, "nurburgring", "cw", seed=2)
    assert summary.termination == "lap_completed" and summary.laps_completed == 1
    assert 0.8 < summary.max_distance_to_line_m < 2.0 and off_line > 0.01       # real recoveries, far from the edge


@pytest.mark.slow
@pytest.mark.parametrize("direction", ["cw", "ccw"])
@pytest.mark.parametrize("name", CIRCUITS.names())
def test_recordings_with_swerves_stay_on_every_circuit(tmp_path, name, direction):
    results = [record_with_swerves(tmp_path, name, direction, seed) for seed in (0, 1, 2, 3)]
    for seed, (summary, off_line) in enumerate(results):
        print(f"\n{name} {direction} seed {seed}: {summary.termination}, max {summary.max_distance_to_line_m:.2f} m "
              f"from the line, {off_line:.1%} of the lap more than 0.3 m off")
        assert summary.termination == "lap_completed"
        assert summary.max_distance_to_line_m < 2.0                          # the road's edge is 3 m away
    assert max(s.max_distance_to_line_m for s, _ in results) > 0.5 and np.mean([o for _, o in results]) > 0.01
