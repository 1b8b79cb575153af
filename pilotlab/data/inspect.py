"""What a bag (or dataset folder) holds: topics, types, counts, duration, image size, v/w ranges."""
from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pilotlab.data.bags import COMMAND_TYPES, bag_format, find_topic, messages, open_bag, read_commands
from pilotlab.data.folder_rows import is_dataset_folder, read_rows
from pilotlab.data.images import COMPRESSED, IMAGE_TYPES, encoding_of, image_size, raw_pixels
from pilotlab.data.topics import COMMAND_TOPIC
from pilotlab.errors import BagError


def _range(values: np.ndarray) -> list[float] | None:
    return [float(values.min()), float(values.max())] if len(values) else None


def inspect_recording(path: Path | str, command_topic: str | None = None,
                      progress: Callable[[int, int], None] | None = None, image_topic: str | None = None) -> dict[str, Any]:
    path = Path(path)
    return inspect_folder(path, progress) if is_dataset_folder(path) else inspect_bag(path, command_topic, image_topic)


def inspect_bag(path: Path, command_topic: str | None = None, image_topic: str | None = None) -> dict[str, Any]:
    """`image_topic`, `command_topic`: the topics to check, as the frames job reads them (its errors if one is
    missing or of another type); else every image topic, each with the `problem` that stops the frames job
    reading it (an encoding it does not decode), if any, and the default command topic if the bag has it."""
    with open_bag(path) as reader:
        if command_topic is not None:
            find_topic(reader, path, command_topic, "command", COMMAND_TYPES)
        command_topic = command_topic or COMMAND_TOPIC
        seconds = reader.duration / 1e9
        topics = [{"name": name, "type": info.msgtype, "count": info.msgcount,
                   # N messages over the bag's span make N - 1 intervals (3 frames at 20 Hz read 30 Hz)
                   "rate_hz": round((info.msgcount - 1) / seconds, 2) if seconds > 0 and info.msgcount > 1 else None}
                  for name, info in sorted(reader.topics.items())]
        names = [image_topic] if image_topic else [t["name"] for t in topics if t["type"] in IMAGE_TYPES]
        images = {name: _first_image(reader, path, name) for name in names}
        commands = None
        if reader.topics.get(command_topic) and reader.topics[command_topic].msgtype in COMMAND_TYPES:
            _, labels, damage = read_commands(reader, path, command_topic)
            commands = {"topic": command_topic, "count": len(labels),
                        "v": _range(labels[:, 0]), "w": _range(labels[:, 1])}
            if damage.count:
                commands["damaged"] = damage.summary()
        return {"path": str(path), "format": bag_format(path), "messages": reader.message_count,
                "start_ns": reader.start_time, "end_ns": reader.end_time, "duration_s": round(seconds, 3),
                "topics": topics, "images": images, "command_topic": command_topic, "commands": commands}


def _first_image(reader, path: Path, topic: str) -> dict[str, Any]:
    name, msgtype, connections = find_topic(reader, path, topic, "image", IMAGE_TYPES)
    first = next(messages(reader, path, connections), None)
    if first is None:  # the bag's index (metadata.yaml) announces messages the bag does not hold
        raise BagError(f"{path}: topic {name!r} is announced with {reader.topics[name].msgcount} {msgtype} "
                       f"messages, but none can be read (its metadata does not match its data); "
                       f"record the bag again, or repair it with `ros2 bag reindex`")
    msg = first[1]
    where = f"{path}, topic {name}"
    found = {"type": msgtype, "encoding": encoding_of(msg, msgtype), "size": list(image_size(msg, msgtype, where))}
    if msgtype != COMPRESSED:   # a compressed one was decoded for its size
        try:
            raw_pixels(msg, where)
        except BagError as error:
            found["problem"] = str(error)
    return found


SHOWN_UNREADABLE = 5


def inspect_folder(path: Path, progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """A dataset folder: its rows, and every image it names opened (what `frames` will read), so an
    unreadable image or a mix of sizes shows here, not an hour into a run."""
    rows = read_rows(path)
    labels = np.array([(r.v, r.w) for r in rows], np.float64)
    seconds = (rows[-1].stamp_ns - rows[0].stamp_ns) / 1e9
    return {"path": str(path), "format": "folder", "messages": len(rows), "start_ns": rows[0].stamp_ns,
            "end_ns": rows[-1].stamp_ns, "duration_s": round(seconds, 3),
            "topics": [], "images": {"data.csv": _folder_images(path, rows, progress)},
            "command_topic": "data.csv", "commands": {"topic": "data.csv", "count": len(rows), "v": _range(labels[:, 0]),
                         "w": _range(labels[:, 1])}}


def _folder_images(folder: Path, rows: list, progress: Callable[[int, int], None] | None) -> dict[str, Any]:
    sizes, encodings, unreadable = Counter(), Counter(), []
    for i, row in enumerate(rows):
        image = cv2.imread(str(row.image), cv2.IMREAD_COLOR)
        if image is None:
            unreadable.append(row.image.relative_to(folder).as_posix())
        else:
            sizes[image.shape[:2]] += 1
            encodings[row.image.suffix.lstrip(".").lower() or "?"] += 1
        if progress and (i % 64 == 0 or i == len(rows) - 1):
            progress(i + 1, len(rows))
    common = sizes.most_common(1)[0][0] if sizes else None
    return {"type": "file", "encoding": ", ".join(name for name, _ in encodings.most_common()) or "none",
            "size": list(common) if common else None,
            "sizes": {f"{w}x{h}": count for (h, w), count in sizes.most_common()},
            "unreadable": len(unreadable), "unreadable_first": unreadable[:SHOWN_UNREADABLE]}
