"""Write driving recordings as rosbags: camera images, commands and odometry.

    with BagWriter("run.bag") as bag:              # ".bag": ROS1; otherwise a ROS2 folder
        bag.command(stamp_ns, v=3.0, w=0.1)
        bag.image(stamp_ns, rgb)                   # uint8 H×W×3 RGB

ROS2 bags use sqlite3 storage unless `storage="mcap"`. Images are sensor_msgs/Image rgb8, or
CompressedImage when `compression` is "jpeg" or "png" (then on the `.../compressed` topic).
"""
from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin, Writer as Ros2Writer
from rosbags.typesys import Stores, get_typestore

from pilotlab.data.topics import COMMAND_TOPIC, COMPRESSED_IMAGE_TOPIC, IMAGE_TOPIC, ODOMETRY_TOPIC
from pilotlab.errors import BagError

STORAGES = ("ros1", "sqlite3", "mcap")
IMAGE, COMPRESSED = "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"
TWIST, ODOMETRY = "geometry_msgs/msg/Twist", "nav_msgs/msg/Odometry"


def storage_for(path: Path, storage: str = "auto") -> str:
    if storage == "auto":
        return "ros1" if Path(path).suffix == ".bag" else "sqlite3"
    if storage not in STORAGES:
        raise BagError(f"{path}: unknown bag storage {storage!r}; use one of auto, {', '.join(STORAGES)}")
    if (storage == "ros1") != (Path(path).suffix == ".bag"):
        raise BagError(f"{path}: a ROS1 bag is a file ending in .bag and a ROS2 bag is a folder; "
                       f"rename the output or choose another storage than {storage!r}")
    return storage


class BagWriter:
    def __init__(self, path: Path | str, *, storage: str = "auto", image_topic: str | None = None,
                 command_topic: str = COMMAND_TOPIC, odometry_topic: str = ODOMETRY_TOPIC,
                 compression: str | None = None, frame_id: str = "cameraL"):
        self.path = Path(path)
        self.storage = storage_for(self.path, storage)
        if compression not in (None, "jpeg", "png"):
            raise BagError(f"{path}: image compression {compression!r} is not one of jpeg, png")
        if self.path.exists():
            raise BagError(f"{path} exists already; remove it or choose another output path")
        self.compression, self.frame_id = compression, frame_id
        self.topics = {"image": image_topic or (COMPRESSED_IMAGE_TOPIC if compression else IMAGE_TOPIC),
                       "command": command_topic, "odometry": odometry_topic}
        self.ros1 = self.storage == "ros1"
        self.typestore = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        self.types = self.typestore.types
        self.writer = (Ros1Writer(self.path) if self.ros1 else
                       Ros2Writer(self.path, version=8, storage_plugin=StoragePlugin[self.storage.upper()]))
        self.connections: dict[str, object] = {}
        self.seq = 0

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

    def _header(self, stamp_ns: int, frame_id: str):
        stamp = self.types["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9))
        self.seq += 1
        fields = {"seq": self.seq} if self.ros1 else {}
        return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id, **fields)

    def _vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0):
        return self.types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def image(self, stamp_ns: int, rgb: np.ndarray) -> None:
        """One camera image, uint8 H×W×3 RGB."""
        header = self._header(stamp_ns, self.frame_id)
        if self.compression:
            ok, data = cv2.imencode(f".{'jpg' if self.compression == 'jpeg' else 'png'}",
                                    cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            msg = self.types[COMPRESSED](header=header, format=self.compression, data=data.reshape(-1))
            return self._write("image", COMPRESSED, stamp_ns, msg)
        height, width = rgb.shape[:2]
        msg = self.types[IMAGE](header=header, height=height, width=width, encoding="rgb8",
                                is_bigendian=0, step=width * 3,
                                data=np.ascontiguousarray(rgb, np.uint8).reshape(-1))
        self._write("image", IMAGE, stamp_ns, msg)

    def command(self, stamp_ns: int, v: float, w: float) -> None:
        """One geometry_msgs/Twist: linear.x = v (m/s), angular.z = w (rad/s)."""
        msg = self.types[TWIST](linear=self._vector(x=v), angular=self._vector(z=w))
        self._write("command", TWIST, stamp_ns, msg)

    def odometry(self, stamp_ns: int, x: float, y: float, yaw: float, v: float = 0.0, w: float = 0.0) -> None:
        """One nav_msgs/Odometry of a car on the ground plane."""
        t = self.types
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
        twist = t["geometry_msgs/msg/Twist"](linear=self._vector(x=v), angular=self._vector(z=w))
        covariance = np.zeros(36, np.float64)
        msg = t[ODOMETRY](header=self._header(stamp_ns, "odom"), child_frame_id="base_link",
                          pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance),
                          twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=covariance))
        self._write("odometry", ODOMETRY, stamp_ns, msg)
