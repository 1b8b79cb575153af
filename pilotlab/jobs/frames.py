"""The `frames` job: one recording (a bag or a dataset folder) -> preprocessed frames in the store.

Where the recording comes from (exactly one):
  inputs["bag"]      a user's ROS1 .bag, ROS2 bag folder (or its .db3 / .mcap) or DeepLearningStudio
                     dataset folder; an input file, so its content is in the job key;
  deps["bag"]        a `record` job; its artifacts folder holds the bag at `result["bag"]` (or
                     `result["path"]`), and its `result["topics"]` ({"image", "cmd_vel"}) are the
                     default topics;
  params["path"]     the same as inputs["bag"], for jobs built by hand (not hashed: prefer inputs).

params: pilotlab.specs.frames.FramesSpec (topics, the preprocessing crop and size; a label for jobs built by
hand: a planned job is labelled by its name, which is not in its key).

artifacts: a FrameSet (frames.npy uint8 [N, 66, 200, 3] RGB, labels.npy float32 [N, 2] physical v, w,
recording.npy, meta.json), loaded by `FrameSet.load(dep.artifacts)`.
result: frames, dropped (images before the first command), stale_commands ({frames, max_age_s, limit_s}:
frames labelled by a command older than pilotlab.data.bags.STALE_COMMAND_S; absent when none), damaged (per
topic: count, times_s, reason of the messages left out as damaged; absent when none), source, format (ros1 | ros2-sqlite3 |
ros2-mcap | folder), image_topic, command_topic, encoding, image_size [h, w], duration_s,
v_range, w_range, preprocess (settings), decode_fps, label.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from matrix.kinds import JobContext
from pilotlab.data.bags import Topics, read_frames
from pilotlab.data.topics import COMMAND_TOPIC
from pilotlab.errors import PilotlabError
from pilotlab.specs.frames import FramesSpec, PreprocessConfig


def recording_path(ctx: JobContext) -> Path:
    """The bag or folder this job reads (see the module docstring)."""
    sources = []
    if "bag" in ctx.inputs:
        sources.append(Path(ctx.inputs["bag"]))
    if "bag" in ctx.deps:
        dep = ctx.dep("bag")
        relative = dep.result.get("bag") or dep.result.get("path")
        if not relative:
            raise PilotlabError(f"{ctx.name}: dependency {dep.name or dep.key} names no bag in its result "
                                "(expected 'bag' or 'path', relative to its artifacts)")
        sources.append(Path(dep.artifacts) / relative)
    if not sources and ctx.spec.path:
        sources.append(Path(ctx.spec.path))
    if len(sources) != 1:
        raise PilotlabError(f"{ctx.name}: a frames job reads exactly one recording (an input 'bag', a "
                            f"'bag' dependency or a 'path' param); it was given {len(sources)}")
    return sources[0]


def job_topics(ctx: JobContext) -> Topics:
    """Topics named in params, else those a record dependency reports, else the conventions'."""
    recorded = dict(ctx.dep("bag").result.get("topics") or {}) if "bag" in ctx.deps else {}
    return Topics(ctx.spec.image_topic or recorded.get("image"),
                  ctx.spec.command_topic or recorded.get("cmd_vel") or COMMAND_TOPIC)


def summary(frameset, seconds: float) -> dict[str, Any]:
    labels, meta = np.asarray(frameset.labels), frameset.meta
    keys = ("frames", "dropped", "damaged", "stale_commands", "source", "format", "image_topic", "command_topic", "encoding",
            "image_size", "preprocess")
    return {**{k: meta[k] for k in keys if k in meta},
            "duration_s": round((meta["end_ns"] - meta["start_ns"]) / 1e9, 3),
            "v_range": [float(labels[:, 0].min()), float(labels[:, 0].max())],
            "w_range": [float(labels[:, 1].min()), float(labels[:, 1].max())],
            "decode_fps": round(len(frameset) / max(seconds, 1e-9), 1)}


def run_frames(ctx: JobContext) -> dict[str, Any]:
    spec: FramesSpec = ctx.spec
    path = recording_path(ctx)
    config = PreprocessConfig.from_params(spec.as_dict())
    topics = job_topics(ctx)
    label = spec.label or ctx.name.removeprefix("frames ") or path.name
    ctx.log.info("reading %s", path)
    started = time.perf_counter()
    frameset = read_frames(path, config, topics, progress=lambda done, total: ctx.progress(
        done, total, f"decoding {label}"))
    seconds = time.perf_counter() - started
    frameset.meta["label"] = label
    frameset.save(ctx.out)
    result = {**summary(frameset, seconds), "label": label}
    ctx.log.info("%d frames from %s (%.0f frames/s)", result["frames"], path, result["decode_fps"])
    for damage in result.get("damaged", []):   # left out: under pilotlab.data.damage.MAX_SHARE of the topic
        ctx.log.warning("%s: %d damaged message(s) left out on %s (at %s s: %s)", path, damage["count"],
                        damage["topic"], damage["times_s"], damage["reason"])
    if stale := result.get("stale_commands"):    # the command stream stopped for a while: said, not hidden
        ctx.log.warning("%s: %d frame(s) labelled by a command more than %g s old (up to %.1f s): the commands on %s "
                        "stopped while images went on", path, stale["frames"], stale["limit_s"], stale["max_age_s"],
                        topics.command)
    return result
