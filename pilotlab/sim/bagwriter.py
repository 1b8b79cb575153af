"""Writing the simulator's messages to a ROS1 bag or a ROS2 bag folder with `rosbags`.

Topics (docs/CONVENTIONS.md): `/F1ROS/cameraL/image_raw` sensor_msgs/Image rgb8 (or
`/F1ROS/cameraL/image_raw/compressed` sensor_msgs/CompressedImage, format "rgb8; jpeg compressed
bgr8" as ROS's compressed_image_transport writes it), `/F1ROS/cmd_vel` geometry_msgs/Twist,
`/F1ROS/odom` nav_msgs/Odometry, and `/pilotlab/metadata` std_msgs/String: one JSON message at
time 0 with the circuit, direction, seed and the other settings (ROS2 bags also carry it in
metadata.yaml custom_data as `pilotlab`). Every message is stamped in simulated time (header stamp
and bag time alike, from 0).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from rosbags.typesys import Stores, get_typestore

from pilotlab.errors import PilotlabError

IMAGE_TOPIC = "/F1ROS/cameraL/image_raw"
COMPRESSED_TOPIC = "/F1ROS/cameraL/image_raw/compressed"
CMD_TOPIC = "/F1ROS/cmd_vel"
ODOM_TOPIC = "/F1ROS/odom"
METADATA_TOPIC = "/pilotlab/metadata"
FORMATS = ("ros1", "ros2")
COMPRESSIONS = ("jpeg", "png")
JPEG_QUALITY = 90


def bag_path(out: Path, format: str) -> Path:
    """Where a bag of `format` goes: ROS1 is a `.bag` file, ROS2 a folder."""
    out = Path(out)
    if format == "ros1" and out.suffix != ".bag":
        return out.with_name(out.name + ".bag")
    return out


class BagWriter:
    """Open a bag, write messages stamped in simulated seconds, close it (also on errors)."""

    def __init__(self, path: Path, format: str = "ros1", compressed: str | None = None):
        if format not in FORMATS:
            raise PilotlabError(f"unknown bag format {format!r}; use one of: {', '.join(FORMATS)}")
        if compressed is not None and compressed not in COMPRESSIONS:
            raise PilotlabError(f"unknown image compression {compressed!r}; use one of: {', '.join(COMPRESSIONS)}")
        self.path, self.format, self.compressed = Path(path), format, compressed
        if self.path.exists():
            raise PilotlabError(f"{self.path} already exists; remove it or record to another path")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if format == "ros1":
            from rosbags.rosbag1 import Writer
            self.store, self._writer = get_typestore(Stores.ROS1_NOETIC), Writer(self.path)
            self._serialize = self.store.serialize_ros1
        else:
            from rosbags.rosbag2 import Writer
            self.store, self._writer = get_typestore(Stores.ROS2_HUMBLE), Writer(self.path, version=8)
            self._serialize = self.store.serialize_cdr
        self._writer.open()
        self._connections: dict[str, Any] = {}
        self._seq: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self.image_topic = COMPRESSED_TOPIC if compressed else IMAGE_TOPIC
        for topic, msgtype in ((self.image_topic, "sensor_msgs/msg/CompressedImage" if compressed else
                                "sensor_msgs/msg/Image"), (CMD_TOPIC, "geometry_msgs/msg/Twist"),
                               (ODOM_TOPIC, "nav_msgs/msg/Odometry"), (METADATA_TOPIC, "std_msgs/msg/String")):
            self._connections[topic] = self._writer.add_connection(topic, msgtype, typestore=self.store)
            self.counts[topic] = 0

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- messages -------------------------------------------------------------------------------
    def _write(self, topic: str, message, time_s: float) -> None:
        connection = self._connections[topic]
        self._writer.write(connection, to_nanoseconds(time_s), self._serialize(message, connection.msgtype))
        self.counts[topic] += 1

    def _header(self, topic: str, time_s: float, frame_id: str):
        types = self.store.types
        nanoseconds = to_nanoseconds(time_s)
        stamp = types["builtin_interfaces/msg/Time"](sec=nanoseconds // 10**9, nanosec=nanoseconds % 10**9)
        if self.format == "ros1":
            self._seq[topic] = self._seq.get(topic, -1) + 1
            return types["std_msgs/msg/Header"](seq=self._seq[topic], stamp=stamp, frame_id=frame_id)
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def metadata(self, data: dict[str, Any]) -> None:
        text = json.dumps(data, sort_keys=True)
        self._write(METADATA_TOPIC, self.store.types["std_msgs/msg/String"](data=text), 0.0)
        if self.format == "ros2":
            self._writer.set_custom_data("pilotlab", text)

    def image(self, rgb: np.ndarray, time_s: float) -> None:
        types, header = self.store.types, self._header(self.image_topic, time_s, "camera")
        if self.compressed:
            encoded = encode_image(rgb, self.compressed)
            message = types["sensor_msgs/msg/CompressedImage"](
                header=header, format=f"rgb8; {self.compressed} compressed bgr8", data=encoded)
        else:
            height, width = rgb.shape[:2]
            message = types["sensor_msgs/msg/Image"](
                header=header, height=height, width=width, encoding="rgb8", is_bigendian=0, step=3 * width,
                data=np.ascontiguousarray(rgb, dtype=np.uint8).reshape(-1))
        self._write(self.image_topic, message, time_s)

    def command(self, v: float, w: float, time_s: float) -> None:
        types = self.store.types
        vector = types["geometry_msgs/msg/Vector3"]
        message = types["geometry_msgs/msg/Twist"](linear=vector(x=float(v), y=0.0, z=0.0),
                                                   angular=vector(x=0.0, y=0.0, z=float(w)))
        self._write(CMD_TOPIC, message, time_s)

    def odometry(self, info: dict[str, Any], time_s: float) -> None:
        types = self.store.types
        vector, zeros = types["geometry_msgs/msg/Vector3"], np.zeros(36, dtype=np.float64)
        x, y, z = info["position"]
        qx, qy, qz, qw = info["orientation"]
        pose = types["geometry_msgs/msg/Pose"](position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z),
                                               orientation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw))
        twist = types["geometry_msgs/msg/Twist"](linear=vector(x=float(info["speed"]), y=0.0, z=0.0),
                                                 angular=vector(x=0.0, y=0.0, z=float(info["yaw_rate"])))
        message = types["nav_msgs/msg/Odometry"](
            header=self._header(ODOM_TOPIC, time_s, "odom"), child_frame_id="base_link",
            pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=zeros),
            twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=zeros))
        self._write(ODOM_TOPIC, message, time_s)


def to_nanoseconds(time_s: float) -> int:
    return int(round(time_s * 1e9))


def encode_image(rgb: np.ndarray, compression: str) -> np.ndarray:
    """JPEG or PNG bytes of an RGB image, as OpenCV writes them (BGR inside, as ROS does)."""
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if compression == "jpeg" else [cv2.IMWRITE_PNG_COMPRESSION, 1]
    ok, encoded = cv2.imencode(".jpg" if compression == "jpeg" else ".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                               params)
    if not ok:
        raise PilotlabError(f"OpenCV could not encode a {rgb.shape} image as {compression}")
    return encoded.reshape(-1)
