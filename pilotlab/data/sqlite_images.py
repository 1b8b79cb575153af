"""Fast path for raw images in ROS2 sqlite3 bags: only the rows the crop keeps leave the database.

Reading a 640×480 rgb8 message through rosbags copies the whole 0.9 MB blob out of sqlite, which
costs more than everything else per frame. Here each message's CDR header (a few dozen bytes) is
parsed with `struct`, and the kept rows are read from the blob straight into a numpy buffer
(apsw's incremental blob I/O), then preprocessed by the same `finish` as every other image.
Used only where it applies (one uncompressed .db3, sensor_msgs/Image, little-endian CDR); the
bag reader falls back to rosbags otherwise, with identical frames (a test checks it).
"""
from __future__ import annotations

import struct
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import apsw
import cv2
import numpy as np

from pilotlab.data.images import CHANNELS, IMAGE, raw_pixels
from pilotlab.data.preprocess import PreprocessConfig, finish
from pilotlab.errors import BagError

HEAD = 256                      # bytes read first: a header with short frame_id and encoding fits
CDR_LE = b"\x00\x01"


@dataclass(frozen=True)
class ImageHeader:
    height: int
    width: int
    encoding: str
    step: int
    data_offset: int            # where the pixels start in the serialized message


class _Fields:
    """The fields of sensor_msgs/Image, in order, as ROS2's header (CDR, little-endian) lays them."""

    def __init__(self, buffer: bytes):
        self.buffer, self.position = buffer, 4          # after the encapsulation header

    def align(self, size: int) -> None:
        self.position += -(self.position - 4) % size

    def uint32(self) -> int:
        self.align(4)
        (value,) = struct.unpack_from("<I", self.buffer, self.position)
        self.position += 4
        return value

    def string(self) -> str:
        length = self.uint32()
        text = bytes(self.buffer[self.position:self.position + length])
        if len(text) < length:
            raise IndexError("header longer than read")
        self.position += length
        return text.rstrip(b"\x00").decode()


def parse_header(buffer: bytes) -> ImageHeader:
    """The shape of a CDR sensor_msgs/Image from its first bytes (IndexError: read more)."""
    fields = _Fields(buffer)
    fields.uint32(), fields.uint32()                    # stamp: sec, nanosec
    fields.string()                                     # frame_id
    height, width, encoding = fields.uint32(), fields.uint32(), fields.string()
    fields.position += 1                                # is_bigendian
    step, _ = fields.uint32(), fields.uint32()          # step, length of data
    return ImageHeader(height, width, encoding, step, fields.position)


def applies(path: Path, reader, msgtype: str) -> Path | None:
    """The .db3 file to read directly, or None when the fast path does not apply."""
    files = sorted(path.glob("*.db3")) if path.is_dir() else [path] if path.suffix == ".db3" else []
    zipped = path.is_dir() and any(path.glob("*.zstd"))
    if msgtype != IMAGE or len(files) != 1 or zipped or not reader.is2:
        return None
    if any(r.compression_mode for r in reader.readers):
        return None
    return files[0]


class SqliteImages:
    """The images of one topic in a .db3 file (one connection: one per thread)."""

    def __init__(self, database: Path, topic: str, where: str):
        self.database, self.where = database, where
        self.connection = apsw.Connection(str(database), flags=apsw.SQLITE_OPEN_READONLY)
        self.topic_ids = [row[0] for row in self.connection.execute("SELECT id FROM topics WHERE name = ?", (topic,))]
        self.first_header: ImageHeader | None = None

    def close(self) -> None:
        self.connection.close()

    def rows(self, start: int) -> list[tuple[int, int]]:
        """(rowid, time stamp) of the topic's messages at or after `start`, in time order."""
        marks = ",".join("?" * len(self.topic_ids))
        query = (f"SELECT id, timestamp FROM messages WHERE topic_id IN ({marks}) AND timestamp >= ? "
                 "ORDER BY timestamp, id")
        return list(self.connection.execute(query, (*self.topic_ids, start)))

    def decode(self, rows: list[tuple[int, int]], positions: np.ndarray, config: PreprocessConfig,
               out: np.ndarray, done: Callable[[], None],
               on_damage: Callable[[int, Exception], None] | None = None) -> None:
        """Preprocess the image of rows[i] into out[i] for each i in `positions`; with `on_damage`,
        a message that cannot be decoded is reported there (position, error) instead of raised."""
        buffer = np.empty(0, np.uint8)
        for i in positions:
            blob = self.connection.blob_open("main", "messages", "data", rows[i][0], False)
            try:
                buffer = self._decode(blob, config, buffer, out[i])
            except (BagError, ValueError, cv2.error) as error:
                if on_damage is None:
                    raise
                on_damage(int(i), error)
            finally:
                blob.close()
            done()


    def _decode(self, blob, config: PreprocessConfig, buffer: np.ndarray, out: np.ndarray) -> np.ndarray:
        header = self._header(blob)
        channels = CHANNELS.get(header.encoding)
        if channels is None or blob.length() < header.data_offset + header.height * header.step:
            return self._whole(blob, config, out)       # let the general decoder explain the problem
        rows = config.rows(header.height)
        count = (rows.stop - rows.start) * header.step
        if len(buffer) < count:
            buffer = np.empty(count, np.uint8)
        blob.seek(header.data_offset + rows.start * header.step)
        blob.read_into(buffer, 0, count)
        kept = buffer[:count].reshape(-1, header.step)[:, :header.width * channels]
        finish(kept.reshape(len(kept), header.width, channels) if channels == 3 else kept,
               config, header.encoding, out)
        self.first_header = self.first_header or header
        return buffer

    def _header(self, blob) -> ImageHeader:
        size = min(HEAD, blob.length())
        while True:
            blob.seek(0)
            head = blob.read(size)
            if head[:2] != CDR_LE:
                raise BagError(f"{self.where}: an image message is not little-endian CDR; the bag is corrupt, "
                               "record it again")
            try:
                return parse_header(head)
            except (IndexError, struct.error, UnicodeDecodeError):
                if size >= blob.length():
                    raise BagError(f"{self.where}: an image message is too short; the bag is corrupt, "
                                   "record it again") from None
                size = min(size * 4, blob.length())

    def _whole(self, blob, config: PreprocessConfig, out: np.ndarray) -> np.ndarray:
        """An image the fast path cannot take apart: through the full decoder (for its errors)."""
        from rosbags.typesys import Stores, get_typestore

        blob.seek(0)
        try:
            msg = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(blob.read(), IMAGE)
        except Exception as error:  # rosbags raises several types for a damaged message
            raise BagError(f"{self.where}: an image message cannot be decoded ({error}); the bag is corrupt, "
                           "record it again") from None
        finish(raw_pixels(msg, self.where)[config.rows(int(msg.height))], config, msg.encoding, out)
        return np.empty(0, np.uint8)


def read_images(database: Path, topic: str, where: str, start: int, config: PreprocessConfig,
                threads: int = 1, progress: Callable[[int, int], None] | None = None,
                on_damage: Callable[[int, Exception], None] | None = None
                ) -> tuple[np.ndarray, np.ndarray, ImageHeader | None]:
    """(frames, time stamps, first image's header) of the images at or after `start`. With several
    threads, each decodes a contiguous part on its own connection; apsw and OpenCV release the GIL."""
    first = SqliteImages(database, topic, where)
    rows = first.rows(start)
    frames = np.empty((len(rows), config.height, config.width, 3), np.uint8)
    counter, lock = [0], threading.Lock()

    def done() -> None:
        with lock:
            counter[0] += 1
            if progress and counter[0] % 32 == 0:
                progress(counter[0], len(rows))

    parts = np.array_split(np.arange(len(rows)), max(1, min(threads, len(rows))))
    readers = [first] + [SqliteImages(database, topic, where) for _ in parts[1:]]
    try:
        with ThreadPoolExecutor(len(parts)) as pool:
            for future in [pool.submit(r.decode, rows, part, config, frames, done, on_damage) for r, part in zip(readers, parts)]:
                future.result()
    finally:
        for reader in readers:
            reader.close()
    if progress:
        progress(len(rows), len(rows))
    header = next((r.first_header for r in readers if r.first_header), None)
    return frames, np.array([stamp for _, stamp in rows], np.int64), header
