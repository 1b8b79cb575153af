"""Write driving recordings as rosbags with `rosbags`: camera images, commands, odometry and
pilotlab's metadata. The simulator's recorder and `pilotlab dataset convert` both write with it.

    with BagWriter("run.bag") as bag:              # ".bag": ROS1; otherwise a ROS2 folder (sqlite3)
        bag.metadata({"circuit": "montreal"})      # /pilotlab/metadata at time 0 (+ ROS2 custom_data)
        bag.command(stamp_ns, v=3.0, w=0.1)        # geometry_msgs/Twist
        bag.image(stamp_ns, rgb)                   # uint8 H×W×3 RGB: sensor_msgs/Image rgb8
        bag.odometry(stamp_ns, (x, y, z), (qx, qy, qz, qw), v=3.0, w=0.1)

ROS2 bags use sqlite3 storage unless `storage="mcap"`. With `compression` "jpeg" or "png", images
are sensor_msgs/CompressedImage on the `.../compressed` topic, format "rgb8; jpeg compressed bgr8"
as ROS's compressed_image_transport writes it (BGR bytes inside). Topics default to
docs/CONVENTIONS.md's (pilotlab.data.topics); every message is stamped in the given time, header
stamp and bag time alike.
"""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin, Writer as Ros2Writer
from rosbags.typesys import Stores, get_typestore

from pilotlab.data.topics import (COMMAND_TOPIC, COMPRESSED_IMAGE_TOPIC, IMAGE_TOPIC, METADATA_TOPIC,
                                  ODOMETRY_TOPIC)
from pilotlab.errors import BagError

STORAGES = ("ros1", "sqlite3", "mcap")
COMPRESSIONS = ("jpeg", "png")
JPEG_QUALITY = 90
IMAGE, COMPRESSED = "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"
TWIST, ODOMETRY, STRING = "geometry_msgs/msg/Twist", "nav_msgs/msg/Odometry", "std_msgs/msg/String"


def bag_path(out: Path | str, format: str) -> Path:
    """Where a bag of `format` goes: ROS1 is a `.bag` file (the suffix added if missing), ROS2 a folder."""
    out = Path(out)
    return out.with_name(out.name + ".bag") if format == "ros1" and out.suffix != ".bag" else out


def storage_for(path: Path, storage: str = "auto") -> str:
    if storage == "auto":
        return "ros1" if Path(path).suffix == ".bag" else "sqlite3"
    if storage not in STORAGES:
        raise BagError(f"{path}: unknown bag storage {storage!r}; use one of auto, {', '.join(STORAGES)}")
    if (storage == "ros1") != (Path(path).suffix == ".bag"):
        raise BagError(f"{path}: a ROS1 bag is a file ending in .bag and a ROS2 bag is a folder; "
                       f"rename the output, or write the other kind (`record --format`, "
                       f"`dataset convert --storage`; asked: {'ROS1' if storage == 'ros1' else 'ROS2'})")
    return storage


def check_new_bag(path: Path) -> None:
    """A bag is written where nothing is yet, below folders (not a file where a folder goes)."""
    if path.exists():
        raise BagError(f"{path} already exists; remove it or choose another output path")
    folder = next((p for p in path.parents if p.exists()), None)
    if folder is not None and not folder.is_dir():
        raise BagError(f"{folder} is a file, so {path} cannot be written below it")


TOPIC_NAME = re.compile(r"/?[A-Za-z_~][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")   # a ROS graph resource name


def check_topics(path: Path, topics: dict[str, str]) -> None:
    """Each topic a ROS name, no two the same: one topic for two message types made a bag no reader
    could use (`--image-topic /same --command-topic /same`), and an empty name was taken for the default."""
    for role, topic in topics.items():
        if not isinstance(topic, str) or not TOPIC_NAME.fullmatch(topic):
            raise BagError(f"{path}: the {role} topic {topic!r} is not a ROS topic name (e.g. /camera/image_raw: "
                           "letters, digits, _ and /)")
    named = list(topics.values())
    if same := sorted({t for t in named if named.count(t) > 1}):
        roles = [role for role, topic in topics.items() if topic == same[0]]
        raise BagError(f"{path}: the {' and '.join(roles)} topics are both {same[0]!r}; give each its own topic")


class BagWriter:
    def __init__(self, path: Path | str, *, storage: str = "auto", image_topic: str | None = None,
                 command_topic: str = COMMAND_TOPIC, odometry_topic: str = ODOMETRY_TOPIC,
                 compression: str | None = None, frame_id: str = "camera"):
        self.path = Path(path)
        self.storage = storage_for(self.path, storage)
        if compression not in (None, *COMPRESSIONS):
            raise BagError(f"{path}: image compression {compression!r} is not one of {', '.join(COMPRESSIONS)}")
        check_new_bag(self.path)
        self.compression, self.frame_id = compression, frame_id
        self.image_topic = (COMPRESSED_IMAGE_TOPIC if compression else IMAGE_TOPIC) if image_topic is None else image_topic
        self.topics = {"image": self.image_topic, "command": command_topic, "odometry": odometry_topic,
                       "metadata": METADATA_TOPIC}
        check_topics(self.path, self.topics)
        self.ros1 = self.storage == "ros1"
        self.typestore = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        self.types = self.typestore.types
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.writer = (Ros1Writer(self.path) if self.ros1 else
                       Ros2Writer(self.path, version=8, storage_plugin=StoragePlugin[self.storage.upper()]))
        self.connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {topic: 0 for topic in self.topics.values()}   # messages per topic
        self.seq: dict[str, int] = {}

    def __enter__(self) -> BagWriter:
        self.writer.open()
        return self

    def __exit__(self, *exc) -> None:
        self.writer.close()

    def _write(self, role: str, msgtype: str, stamp_ns: int, msg) -> None:
        if role not in self.connections:
            self.connections[role] = self.writer.add_connection(self.topics[role], msgtype,
                                                                typestore=self.typestore)
        data = (self.typestore.serialize_ros1(msg, msgtype) if self.ros1
                else self.typestore.serialize_cdr(msg, msgtype))
        self.writer.write(self.connections[role], int(stamp_ns), data)
        self.counts[self.topics[role]] += 1

    def _header(self, role: str, stamp_ns: int, frame_id: str):
        stamp = self.types["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9))
        if not self.ros1:
            return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
        self.seq[role] = self.seq.get(role, -1) + 1   # ROS1 headers count per topic from 0
        return self.types["std_msgs/msg/Header"](seq=self.seq[role], stamp=stamp, frame_id=frame_id)

    def _vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0):
        return self.types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def metadata(self, data: dict[str, Any]) -> None:
        """One JSON std_msgs/String at time 0 (ROS2 bags: also metadata.yaml custom_data `pilotlab`)."""
        text = json.dumps(data, sort_keys=True)
        self._write("metadata", STRING, 0, self.types[STRING](data=text))
        if not self.ros1:
            self.writer.set_custom_data("pilotlab", text)

    def image(self, stamp_ns: int, rgb: np.ndarray) -> None:
        """One camera image, uint8 H×W×3 RGB."""
        header = self._header("image", stamp_ns, self.frame_id)
        if self.compression:
            msg = self.types[COMPRESSED](header=header, format=f"rgb8; {self.compression} compressed bgr8",
                                         data=encode_image(rgb, self.compression))
            return self._write("image", COMPRESSED, stamp_ns, msg)
        height, width = rgb.shape[:2]
        msg = self.types[IMAGE](header=header, height=height, width=width, encoding="rgb8",
                                is_bigendian=0, step=width * 3,
                                data=np.ascontiguousarray(rgb, np.uint8).reshape(-1))
        self._write("image", IMAGE, stamp_ns, msg)

    def command(self, stamp_ns: int, v: float, w: float) -> None:
        """One geometry_msgs/Twist: linear.x = v (m/s), angular.z = w (rad/s)."""
        self._write("command", TWIST, stamp_ns, self.types[TWIST](linear=self._vector(x=v), angular=self._vector(z=w)))

    def odometry(self, stamp_ns: int, position, orientation, v: float = 0.0, w: float = 0.0) -> None:
        """One nav_msgs/Odometry: position (x, y, z), orientation quaternion (x, y, z, w), speeds."""
        t = self.types
        (x, y, z), (qx, qy, qz, qw) = position, orientation
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z)),
            orientation=t["geometry_msgs/msg/Quaternion"](x=float(qx), y=float(qy), z=float(qz), w=float(qw)))
        twist = t[TWIST](linear=self._vector(x=v), angular=self._vector(z=w))
        covariance = np.zeros(36, np.float64)
        msg = t[ODOMETRY](header=self._header("odometry", stamp_ns, "odom"), child_frame_id="base_link",
                          pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance),
                          twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=covariance))
        self._write("odometry", ODOMETRY, stamp_ns, msg)


def encode_image(rgb: np.ndarray, compression: str) -> np.ndarray:
    """JPEG or PNG bytes of an RGB image, as OpenCV writes them (BGR inside, as ROS does)."""
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if compression == "jpeg" else [cv2.IMWRITE_PNG_COMPRESSION, 1]
    ok, encoded = cv2.imencode(".jpg" if compression == "jpeg" else ".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                               params)
    if not ok:
        raise BagError(f"OpenCV could not encode a {rgb.shape} image as {compression}")
    return encoded.reshape(-1)


def to_nanoseconds(time_s: float) -> int:
    return int(round(time_s * 1e9))
