"""Tiny bags written with rosbags directly (not with pilotlab's writer), so the reader is tested
against an independent writer; and synthetic camera images."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin, Writer as Ros2Writer
from rosbags.typesys import Stores, get_typestore

IMAGE_TOPIC = "/F1ROS/cameraL/image_raw"
COMMAND_TOPIC = "/F1ROS/cmd_vel"
KINDS = ("ros1", "sqlite3", "mcap")


def images(n: int, height: int = 60, width: int = 80, seed: int = 0) -> list[np.ndarray]:
    """Smooth random RGB images (so jpeg stays close to the original)."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (n, height // 10 + 1, width // 10 + 1, 3), dtype=np.uint8)
    return [cv2.resize(s, (width, height), interpolation=cv2.INTER_LINEAR) for s in small]


def bag_path(folder: Path, kind: str, name: str = "run") -> Path:
    return folder / (f"{name}.bag" if kind == "ros1" else f"{name}_{kind}")


class RawBag:
    """A bag with any topics and messages, written straight through rosbags."""

    def __init__(self, path: Path, kind: str):
        self.ros1 = kind == "ros1"
        self.store = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        self.writer = (Ros1Writer(path) if self.ros1 else
                       Ros2Writer(path, version=8, storage_plugin=StoragePlugin[kind.upper()]))
        self.connections = {}

    def __enter__(self):
        self.writer.open()
        return self

    def __exit__(self, *exc):
        self.writer.close()

    def write(self, topic: str, msgtype: str, stamp: int, msg) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        data = self.store.serialize_ros1(msg, msgtype) if self.ros1 else self.store.serialize_cdr(msg, msgtype)
        self.writer.write(self.connections[topic], stamp, data)

    def header(self, stamp: int):
        t = self.store.types
        extra = {"seq": 0} if self.ros1 else {}
        return t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9),
                                        frame_id="cam", **extra)

    def image(self, stamp: int, rgb: np.ndarray, encoding: str = "rgb8", topic: str = IMAGE_TOPIC) -> None:
        pixels = {"rgb8": rgb, "bgr8": rgb[..., ::-1], "mono8": rgb[..., 0]}.get(encoding, rgb)
        pixels = np.ascontiguousarray(pixels)
        height, width = pixels.shape[:2]
        step = pixels.strides[0]
        msg = self.store.types["sensor_msgs/msg/Image"](header=self.header(stamp), height=height, width=width,
                                                        encoding=encoding, is_bigendian=0, step=step,
                                                        data=pixels.reshape(-1))
        self.write(topic, "sensor_msgs/msg/Image", stamp, msg)

    def compressed(self, stamp: int, rgb: np.ndarray, fmt: str = "png", topic: str = IMAGE_TOPIC + "/compressed") -> None:
        ok, data = cv2.imencode(".jpg" if "jpeg" in fmt else ".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        msg = self.store.types["sensor_msgs/msg/CompressedImage"](header=self.header(stamp), format=fmt,
                                                                  data=data.reshape(-1))
        self.write(topic, "sensor_msgs/msg/CompressedImage", stamp, msg)

    def twist(self, stamp: int, v: float, w: float, topic: str = COMMAND_TOPIC) -> None:
        t = self.store.types
        vec = t["geometry_msgs/msg/Vector3"]
        self.write(topic, "geometry_msgs/msg/Twist", stamp,
                   t["geometry_msgs/msg/Twist"](linear=vec(x=v, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=w)))

    def twist_stamped(self, stamp: int, v: float, w: float, topic: str = COMMAND_TOPIC) -> None:
        t = self.store.types
        vec = t["geometry_msgs/msg/Vector3"]
        twist = t["geometry_msgs/msg/Twist"](linear=vec(x=v, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=w))
        self.write(topic, "geometry_msgs/msg/TwistStamped", stamp,
                   t["geometry_msgs/msg/TwistStamped"](header=self.header(stamp), twist=twist))


def drive_bag(path: Path, kind: str, frames: list[np.ndarray], *, encoding: str = "rgb8",
              first_command: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A recording: images at 10 Hz, a command every image from `first_command` on, each command
    written 1 ms before its image. Returns the expected labels and the indices of labelled images."""
    labels = []
    with RawBag(path, kind) as bag:
        for i, rgb in enumerate(frames):
            stamp = 10**9 + i * 10**8
            if i >= first_command:
                labels.append((1.0 + 0.1 * i, 0.05 * i - 0.3))
                bag.twist(stamp - 10**6, *labels[-1])
            if encoding in ("jpeg", "png"):
                bag.compressed(stamp, rgb, encoding)
            else:
                bag.image(stamp, rgb, encoding)
    return np.array(labels, np.float32), np.arange(first_command, len(frames))
