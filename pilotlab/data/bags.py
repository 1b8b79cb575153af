"""Read any ROS1 bag or ROS2 bag (sqlite3 or mcap) into a FrameSet, through rosbags' AnyReader.

Each image is paired with the command in force at its time stamp (the latest command at or before
it, by bag time: commands carry no header); images before the first command are dropped. Every
way a bag can be unusable ends in a `BagError` that names the bag (and topic) and says how to fix it.
"""
from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import apsw
import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from pilotlab.data import sqlite_images
from pilotlab.data.damage import Damage, command_problem
from pilotlab.data.folder import read_folder
from pilotlab.data.folder_rows import check_not_system, is_dataset_folder
from pilotlab.data.frames import FrameSet
from pilotlab.data.images import IMAGE_TYPES, encoding_of, frame_from_message, image_size
from pilotlab.data.preprocess import PreprocessConfig
from pilotlab.data.topics import COMMAND_TOPIC, DEFAULT_IMAGE_TOPICS
from pilotlab.errors import BagError, clipped

COMMAND_TYPES = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")
CHUNK = 32                     # frames per task handed to a worker thread
Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Topics:
    image: str | None = None           # None: the first of DEFAULT_IMAGE_TOPICS present
    command: str = COMMAND_TOPIC


def bag_format(path: Path) -> str:
    """'ros1', 'ros2-sqlite3' or 'ros2-mcap'."""
    path = Path(path)
    if path.suffix == ".bag":
        return "ros1"
    names = [p.suffix for p in path.iterdir()] if path.is_dir() else [path.suffix]
    return "ros2-mcap" if ".mcap" in names else "ros2-sqlite3"


def corrupt(path: Path, detail: str) -> BagError:
    # rosbags words some errors with a tuple of arguments: "index looks damaged: ('Header could not be read',)"
    detail = re.sub(r"""\(['"](.*?)['"],\)""", r"\1", detail)
    return BagError(f"{path}: cannot read the bag ({detail}); it is truncated or corrupt. Record it again, "
                    "or repair it (`rosbag reindex` for ROS1, `ros2 bag reindex` for ROS2) and retry")


def check_bag_path(path: Path) -> None:
    """Errors for paths that are not a bag at all, before rosbags sees them."""
    if not path.exists():
        raise BagError(f"{path}: no such bag; check the path (a ROS1 .bag file or a ROS2 bag folder)")
    if path.is_dir() and not (path / "metadata.yaml").exists():
        raise BagError(f"{path}: this folder is not a ROS2 bag (it has no metadata.yaml) nor a dataset folder "
                       "(no data.csv); if its recording was interrupted, run `ros2 bag reindex` on it")
    if path.is_file() and path.suffix not in (".bag", ".db3", ".mcap"):
        raise BagError(f"{path}: not a bag file; a ROS1 bag ends in .bag, a ROS2 bag is a folder "
                       "(or its .db3 / .mcap file)")
    for file in (path, *(sorted(path.iterdir()) if path.is_dir() else ())):
        check_not_system(file, path)


@contextmanager
def open_bag(path: Path | str) -> Iterator[AnyReader]:
    """An open AnyReader on one bag, with rosbags' errors turned into BagErrors."""
    path = Path(path)
    check_bag_path(path)
    reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    try:
        reader.open()
    except Exception as error:  # rosbags raises many types for a damaged file
        raise corrupt(path, _describe(error)) from None
    try:
        if reader.message_count == 0:
            raise BagError(f"{path}: the bag is empty (no messages); record it again, "
                           "or check that the recorder wrote to this path")
        yield reader
    finally:
        reader.close()


def _describe(error: Exception) -> str:
    text = " ".join(str(a) for a in error.args) if error.args else type(error).__name__
    text = " ".join(text.split())             # one line: some readers quote whole message definitions
    return clipped(text, 200) or type(error).__name__


def topic_listing(reader: AnyReader) -> str:
    return ", ".join(f"{name} ({info.msgtype}, {info.msgcount} message{'' if info.msgcount == 1 else 's'})"
                     for name, info in sorted(reader.topics.items()))


def find_topic(reader: AnyReader, path: Path, topic: str | None, role: str,
               types: tuple[str, ...], defaults: tuple[str, ...] = ()) -> tuple[str, str, list]:
    """(topic, msgtype, connections) of the `role` ("image", "command") topic named `topic` (or the
    first default present)."""
    topics = reader.topics
    candidates = [topic] if topic else [t for t in defaults if t in topics]
    if not candidates or candidates[0] not in topics:
        lacks = f"no topic {topic!r}" if topic else f"none of the default {role} topics ({', '.join(defaults)})"
        raise BagError(f"{path}: the bag has {lacks}; topics present: {topic_listing(reader)}; "
                       f"set the {role} topic to one of them{_where_set(role)}")
    name = candidates[0]
    info = topics[name]
    if info.msgtype not in types:
        raise BagError(f"{path}: topic {name!r} carries {info.msgtype}, not {' or '.join(types)}; set the "
                       f"{role} topic to a topic of that type{_where_set(role)} (topics present: {topic_listing(reader)})")
    if info.msgcount == 0:
        raise BagError(f"{path}: topic {name!r} has no messages; record it again or set the {role} topic to "
                       f"another topic{_where_set(role)}")
    return name, info.msgtype, info.connections


def _where_set(role: str) -> str:
    return f" (a recipe's dataset: topics: {{{role}: NAME}}; the command line: --{role}-topic)"


def messages(reader: AnyReader, path: Path, connections: list, start: int | None = None,
             damage: Damage | None = None) -> Iterator[tuple[int, object]]:
    """(time stamp ns, message) of the given connections, in time order. With `damage`, a message
    that cannot be deserialized is counted there and left out; a bag that cannot be read on is an error."""
    stream = reader.messages(connections, start=start)
    while True:
        try:
            connection, stamp, raw = next(stream)
        except StopIteration:
            return
        except Exception as error:  # a damaged chunk, a bad compression block
            raise corrupt(path, _describe(error)) from None
        try:
            msg = reader.deserialize(raw, connection.msgtype)
        except Exception as error:  # a short or garbled message
            if damage is None:
                raise corrupt(path, _describe(error)) from None
            damage.add(stamp, BagError(f"a message cannot be deserialized ({_describe(error)})"))
            continue
        yield stamp, msg


def read_commands(reader: AnyReader, path: Path, topic: str) -> tuple[np.ndarray, np.ndarray, Damage]:
    """(time stamps int64 [M], physical (v, w) float32 [M, 2], damage) of the command topic; a command
    that is damaged (not deserializable, not a finite number of sane size) is left out and counted."""
    name, msgtype, connections = find_topic(reader, path, topic, "command", COMMAND_TYPES)
    damage = Damage(path, name)
    stamps, labels = [], []
    for stamp, msg in messages(reader, path, connections, damage=damage):
        twist = msg.twist if msgtype.endswith("TwistStamped") else msg
        v, w = float(twist.linear.x), float(twist.angular.z)
        problem = command_problem(v, w)
        if problem:
            damage.add(stamp, BagError(f"a command is damaged ({problem})"))
            continue
        stamps.append(stamp)
        labels.append((v, w))
    seen = len(stamps) + len(damage.stamps)
    damage.missing = max(0, sum(c.msgcount for c in connections) - seen)
    damage.check(max(seen, seen + damage.missing))
    return np.asarray(stamps, np.int64), np.asarray(labels, np.float32).reshape(-1, 2), damage


def read_bag(path: Path | str, preprocess: PreprocessConfig, topics: Topics = Topics(), *,
             workers: int | None = None, progress: Progress | None = None) -> FrameSet:
    """Every image at or after the first command, preprocessed, with the command in force.

    `workers` (None: what measured fastest on 2 cores, tests/pilotlab/data/test_benchmark.py):
    raw images in a sqlite3 bag are read and resized by that many threads (default 2: sqlite and
    OpenCV release the GIL); other bags are read by this thread, and `workers` threads resize
    beside it (default 0: rosbags' reading holds the GIL, and threads only added overhead).
    """
    path = Path(path)
    with open_bag(path) as reader:
        cmd_stamps, commands, command_damage = read_commands(reader, path, topics.command)
        order = np.argsort(cmd_stamps, kind="stable")
        cmd_stamps, commands = cmd_stamps[order], commands[order]
        name, msgtype, connections = find_topic(reader, path, topics.image, "image",
                                                IMAGE_TYPES, DEFAULT_IMAGE_TOPICS)
        total = sum(c.msgcount for c in connections)
        where, start = f"{path}, topic {name}", int(cmd_stamps[0])
        damage = Damage(path, name)
        before = sum(1 for _ in reader.messages(connections, stop=start))    # unlabelled: dropped
        database = sqlite_images.applies(path, reader, msgtype)
        threads = min(2, len(os.sched_getaffinity(0))) if workers is None else max(1, workers)
        decoded = (_read_sqlite(database, name, where, start, preprocess, threads, progress, damage) if database else
                   _Decoder(preprocess, msgtype, where, total - before, workers or 0, progress, damage).run(
                       messages(reader, path, connections, start=start, damage=damage)))
    frames, stamps, encoding, size = decoded
    seen = len(stamps) + len(damage.stamps)
    damage.missing = max(0, total - before - seen)
    damage.check(max(total - before, seen))
    if not len(stamps):
        raise BagError(f"{path}: no image on {name!r} at or after the first command on {topics.command!r}; "
                       "the recording has no labelled frames, record it again")
    index = np.searchsorted(cmd_stamps, stamps, side="right") - 1
    stale = _stale_commands(path, name, topics.command, stamps, cmd_stamps[index])
    meta = {"source": str(path), "format": bag_format(path), "image_topic": name, "image_type": msgtype,
            "encoding": encoding, "image_size": size, "command_topic": topics.command,
            "frames": len(stamps), "dropped": before, "start_ns": int(stamps[0]),
            "end_ns": int(stamps[-1]), "preprocess": preprocess.as_dict()}
    damaged = [d.summary() for d in (damage, command_damage) if d.count]
    if damaged:
        meta["damaged"] = damaged
    if stale:
        meta["stale_commands"] = stale
    return FrameSet(frames, commands[index], np.zeros(len(stamps), np.int32), meta)


STALE_COMMAND_S = 1.0   # a frame whose command in force is older: the command stream had stopped


def _stale_commands(path: Path, image_topic: str, command_topic: str, stamps: np.ndarray,
                    in_force: np.ndarray) -> dict[str, Any] | None:
    """The frames labelled by a command older than STALE_COMMAND_S (None when none is): kept, and said.
    When every frame is, the two topics do not belong together (commands stamped by another clock, or
    recorded long before the images): an error, as the labels would be one stale command."""
    ages = (stamps - in_force) / 1e9
    stale = ages > STALE_COMMAND_S
    if not stale.any():
        return None
    if stale.all():
        raise BagError(f"{path}: every image on {image_topic!r} comes {ages.min():.1f} s or more after the last "
                       f"command on {command_topic!r} before it, so every frame would be labelled by a stale "
                       "command; the commands are stamped by another clock or recorded apart from the images: "
                       "give the bag whose commands drive these images")
    return {"frames": int(stale.sum()), "max_age_s": round(float(ages.max()), 3), "limit_s": STALE_COMMAND_S}


Decoded = tuple[np.ndarray, np.ndarray, str, list[int]]   # frames, time stamps, encoding, [h, w]


def _read_sqlite(database: Path, topic: str, where: str, start: int, config: PreprocessConfig,
                 threads: int, progress: Progress | None, damage: Damage) -> Decoded:
    bad: dict[int, Exception] = {}
    try:
        frames, stamps, first = sqlite_images.read_images(database, topic, where, start, config, threads, progress,
                                                          on_damage=bad.__setitem__)
    except apsw.Error as error:
        raise corrupt(database, _describe(error)) from None
    for i in sorted(bad):
        damage.add(stamps[i], bad[i])
    keep = np.setdiff1d(np.arange(len(stamps)), list(bad))
    frames, stamps = (frames[keep], stamps[keep]) if bad else (frames, stamps)
    return frames, stamps, first.encoding if first else "", [first.height, first.width] if first else []


class _Decoder:
    """Preprocess image messages into one preallocated array, optionally on worker threads. A
    message that cannot be decoded is counted in `damage` and left out."""

    def __init__(self, config: PreprocessConfig, msgtype: str, where: str, capacity: int,
                 workers: int, progress: Progress | None, damage: Damage):
        self.config, self.msgtype, self.where, self.workers = config, msgtype, where, workers
        self.frames = np.empty((max(capacity, 1), config.height, config.width, 3), np.uint8)
        self.progress = progress or (lambda done, total: None)
        self.damage, self.bad, self.first = damage, {}, (None, None)

    def _decode(self, chunk: list[tuple[int, int, object]]) -> None:
        for i, stamp, msg in chunk:
            try:
                frame_from_message(msg, self.msgtype, self.config, self.where, out=self.frames[i])
            except Exception as error:   # a damaged message: counted, left out
                self.bad[i] = (stamp, error)
                continue
            if self.first[0] is None or i < self.first[0]:
                self.first = (i, msg)

    def run(self, stream: Iterator[tuple[int, object]]) -> Decoded:
        stamps, chunk, pending = [], [], []
        pool = ThreadPoolExecutor(self.workers) if self.workers else None
        try:
            for stamp, msg in stream:
                if len(stamps) == len(self.frames):   # more messages than the index announced
                    self._finish(pending)
                    self.frames = np.concatenate([self.frames, np.empty_like(self.frames)])
                chunk.append((len(stamps), stamp, msg))
                stamps.append(stamp)
                if len(chunk) == CHUNK:
                    self._submit(pool, chunk, pending)
                    chunk = []
                    self.progress(len(stamps), len(self.frames))
            self._submit(pool, chunk, pending)
            self._finish(pending)
        finally:
            if pool:
                pool.shutdown(cancel_futures=True)
        self.progress(len(stamps), len(stamps))
        return self._result(np.asarray(stamps, np.int64))

    def _result(self, stamps: np.ndarray) -> Decoded:
        for i in sorted(self.bad):
            self.damage.add(*self.bad[i])
        keep = np.setdiff1d(np.arange(len(stamps)), list(self.bad))
        frames, stamps = self.frames[keep] if self.bad else self.frames[:len(stamps)], stamps[keep]
        first = self.first[1]
        if first is None:
            return frames[:0], stamps[:0], "", []
        size = list(image_size(first, self.msgtype, self.where))
        return frames, stamps, encoding_of(first, self.msgtype), size

    @staticmethod
    def _finish(pending: list[Future]) -> None:
        while pending:
            pending.pop(0).result()

    def _submit(self, pool: ThreadPoolExecutor | None, chunk: list, pending: list[Future]) -> None:
        if pool is None:
            return self._decode(chunk)
        pending.append(pool.submit(self._decode, chunk))
        while len(pending) > 2 * self.workers:      # bound the messages held in memory
            pending.pop(0).result()


def read_frames(path: Path | str, preprocess: PreprocessConfig, topics: Topics = Topics(), **kwargs) -> FrameSet:
    """A bag, or a DeepLearningStudio dataset folder (`data.csv` + images), as a FrameSet."""
    path = Path(path)
    if is_dataset_folder(path):
        return read_folder(path, preprocess, progress=kwargs.get("progress"))
    return read_bag(path, preprocess, topics, **kwargs)

