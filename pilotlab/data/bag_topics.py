"""A bag's topic table, read at plan time: a dataset's topics that its bags lack are a recipe error
before anything runs (the frames job would find them one at a time, minutes into a run).

    topics = bag_topics(Path("run.bag"))                  # {topic: type}, None if it cannot be opened
    missing_topics(topics, image=None, command="/cmd_vel")   # [] or [("command", "no command topic '/cmd_vel'")]

Only the index is read (ROS1's connection records, ROS2's metadata), never a message: a bag that
cannot be opened is left to the frames job, which says how it is damaged. Light on purpose: the
planner imports it (no torch, no OpenCV; rosbags' reader only for a recipe that names bags).
"""
from __future__ import annotations

from pathlib import Path

from pilotlab.data.topics import COMMAND_TOPIC, DEFAULT_IMAGE_TOPICS


def bag_topics(path: Path) -> dict[str, str] | None:
    """{topic: message type} of the bag at `path`; None when it cannot be opened."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    try:
        reader.open()
    except Exception:   # damaged or not a bag: the frames job says which, and how to mend it
        return None
    try:
        return {name: info.msgtype for name, info in reader.topics.items()}
    finally:
        reader.close()


def missing_topics(topics: dict[str, str], image: str | None, command: str | None) -> list[tuple[str, str]]:
    """(role, what is missing) of each topic a frames job would not find among `topics`."""
    missing = []
    if image is not None and image not in topics:
        missing.append(("image", f"no image topic {image!r}"))
    if image is None and not any(name in topics for name in DEFAULT_IMAGE_TOPICS):
        missing.append(("image", f"none of the default image topics ({', '.join(DEFAULT_IMAGE_TOPICS)})"))
    if (command or COMMAND_TOPIC) not in topics:
        missing.append(("command", f"no command topic {command or COMMAND_TOPIC!r}"))
    return missing


def listing(topics: dict[str, str]) -> str:
    return ", ".join(f"{name} ({msgtype})" for name, msgtype in sorted(topics.items())) or "none"
