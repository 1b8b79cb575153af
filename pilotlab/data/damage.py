"""Damaged messages in a bag: counted per topic, reported, and an error past a small share.

A bag whose bytes were flipped, or whose last message was cut, often still opens: the damage shows
as single messages that cannot be decoded (an image whose header no longer matches its data, a
command that is not a finite number) or as fewer messages than the bag's index announces. Such
messages are left out and reported (count, topic, times) in the frames job's result and log; when
more than MAX_SHARE of a topic's messages are lost the recording is refused, since the data that
remains may not be what was recorded. (Damage inside raw pixel data cannot be seen: ROS bags carry
no checksums of messages.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pilotlab.errors import BagError

MAX_SHARE = 0.02               # a recording may lose at most 2 % of a topic's messages
MAX_COMMAND = 1e3              # |v| m/s or |w| rad/s beyond this is a damaged number, not a command
SHOWN_TIMES = 5


@dataclass
class Damage:
    """The damaged (or missing) messages of one topic of one bag."""
    path: Path
    topic: str
    stamps: list[int] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    missing: int = 0           # announced by the index or metadata, but absent
    first_error: BagError | None = None

    def add(self, stamp: int, error: Exception) -> None:
        self.stamps.append(int(stamp))
        if isinstance(error, BagError):
            self.first_error = self.first_error or error
            reason = str(error).split(": ", 1)[-1] if str(error).startswith(str(self.path)) else str(error)
        else:
            reason = f"cannot be decoded ({type(error).__name__}: {error})"
        self.reasons.append(reason[:200])

    @property
    def count(self) -> int:
        return len(self.stamps) + self.missing

    def describe(self) -> str:
        parts = []
        if self.stamps:
            times = ", ".join(f"{s / 1e9:.3f}" for s in sorted(self.stamps)[:SHOWN_TIMES])
            more = ", ..." if len(self.stamps) > SHOWN_TIMES else ""
            parts.append(f"{len(self.stamps)} damaged at t={times}{more} s (first: {self.reasons[0]})")
        if self.missing:
            parts.append(f"{self.missing} announced by the bag's index but missing")
        return "; ".join(parts)

    def summary(self) -> dict[str, Any]:
        return {"topic": self.topic, "count": self.count, "missing": self.missing,
                "times_s": [round(s / 1e9, 3) for s in sorted(self.stamps)[:SHOWN_TIMES]],
                "reason": self.reasons[0] if self.reasons else "messages missing"}

    def check(self, total: int) -> None:
        """Raise when more than MAX_SHARE of the topic's `total` messages are lost; when every
        message is damaged alike (a wrong encoding, a bag that is all damage) the first error says
        it best."""
        if not self.count:
            return
        if self.first_error is not None and len(self.stamps) >= total:
            first = str(self.first_error)
            raise (self.first_error if first.startswith(str(self.path)) else
                   BagError(f"{self.path}, topic {self.topic}: {first}"))
        if self.count > MAX_SHARE * max(total, 1):
            # reindexing mends an index that announces absent messages, not a message's contents
            fix = ("record it again, or repair the bag's index (`rosbag reindex`, `ros2 bag reindex`)" if self.missing
                   else "record it again, or mend those messages")
            raise BagError(f"{self.path}, topic {self.topic}: {self.count} of {total} messages are damaged or missing "
                           f"({self.describe()}); more than {MAX_SHARE:.0%} of a recording may not be left out: {fix}")


def command_problem(v: float, w: float) -> str | None:
    """Why (v, w) cannot be a recorded command, or None."""
    for name, value in (("v", v), ("w", w)):
        if not math.isfinite(value) or abs(value) > MAX_COMMAND:
            return f"{name} = {value:g} is not a command"
    return None
