"""Camera images out of ROS messages: sensor_msgs/Image (rgb8, bgr8, mono8) and CompressedImage.

Raw images are not copied: the pixels are a numpy view of the message buffer, and only the rows the
preprocessing keeps are ever touched.
"""
from __future__ import annotations

import cv2
import numpy as np

from pilotlab.data.preprocess import ENCODINGS, PreprocessConfig, preprocess
from pilotlab.errors import BagError

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (IMAGE, COMPRESSED)
CHANNELS = {"rgb8": 3, "bgr8": 3, "mono8": 1}
COMPRESSED_FORMATS = ("jpeg", "png")


def raw_pixels(msg, where: str) -> np.ndarray:
    """H×W×3 (rgb8, bgr8) or H×W (mono8) view of a sensor_msgs/Image's data."""
    channels = CHANNELS.get(msg.encoding)
    if channels is None:
        raise BagError(f"{where}: image encoding {msg.encoding!r} is not supported; "
                       f"use one of {', '.join(ENCODINGS)} (or CompressedImage jpeg/png)")
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if step < width * channels or len(msg.data) < height * step:
        raise BagError(f"{where}: an image message is inconsistent ({width}×{height} {msg.encoding}, "
                       f"step {step}, {len(msg.data)} bytes of data); the bag is corrupt, record it again")
    rows = np.asarray(msg.data)[:height * step].reshape(height, step)[:, :width * channels]
    return rows.reshape(height, width, channels) if channels == 3 else rows


def compressed_format(fmt: str) -> str | None:
    """'jpeg' or 'png' from a CompressedImage format ('jpeg', 'bgr8; jpeg compressed bgr8'...)."""
    words = fmt.lower().replace(";", " ").split()
    found = [f for f in COMPRESSED_FORMATS if f in words or (f == "jpeg" and "jpg" in words)]
    return found[0] if found else None


def decode_compressed(msg, where: str) -> np.ndarray:
    """H×W×3 BGR pixels of a jpeg or png sensor_msgs/CompressedImage."""
    if compressed_format(msg.format) is None:
        raise BagError(f"{where}: compressed image format {msg.format!r} is not supported; "
                       f"use jpeg or png (or a raw Image in {', '.join(ENCODINGS)})")
    pixels = cv2.imdecode(np.asarray(msg.data), cv2.IMREAD_COLOR)
    if pixels is None:
        raise BagError(f"{where}: a {msg.format} image could not be decoded; the bag is corrupt, "
                       "record it again")
    return pixels


def frame_from_message(msg, msgtype: str, config: PreprocessConfig, where: str,
                       out: np.ndarray | None = None) -> np.ndarray:
    """The preprocessed uint8 RGB frame of one image message."""
    if msgtype == COMPRESSED:
        return preprocess(decode_compressed(msg, where), config, "bgr8", out)
    return preprocess(raw_pixels(msg, where), config, msg.encoding, out)


def image_size(msg, msgtype: str, where: str) -> tuple[int, int]:
    """(height, width) of an image message."""
    if msgtype == COMPRESSED:
        return tuple(decode_compressed(msg, where).shape[:2])
    return int(msg.height), int(msg.width)


def encoding_of(msg, msgtype: str) -> str:
    return msg.format if msgtype == COMPRESSED else msg.encoding
