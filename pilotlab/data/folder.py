"""DeepLearningStudio dataset folders: images plus `data.csv` (image_name, v, w, timestamp).

Such a folder is read directly (each row's v, w label its image) or converted into a bag, where each
row becomes a command and an image at the same time stamp, so reading the bag back gives the same
frames and labels.
"""
from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from pilotlab.data.bagwrite import BagWriter
from pilotlab.data.folder_rows import CSV_NAME, read_rows
from pilotlab.data.frames import FrameSet
from pilotlab.data.preprocess import PreprocessConfig, preprocess
from pilotlab.errors import BagError


def load_image(path: Path) -> np.ndarray:
    """uint8 H×W×3 RGB."""
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise BagError(f"{path}: not a readable image; replace or remove it (and its row in {CSV_NAME})")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def read_folder(folder: Path | str, config: PreprocessConfig,
                progress: Callable[[int, int], None] | None = None) -> FrameSet:
    folder = Path(folder)
    rows = read_rows(folder)
    frames = np.empty((len(rows), config.height, config.width, 3), np.uint8)
    size = None
    for i, row in enumerate(rows):
        image = load_image(row.image)
        size = size or list(image.shape[:2])
        preprocess(image, config, out=frames[i])
        if progress and i % 32 == 0:
            progress(i, len(rows))
    if progress:
        progress(len(rows), len(rows))
    labels = np.array([(r.v, r.w) for r in rows], np.float32)
    meta = {"source": str(folder), "format": "folder", "encoding": "png", "image_size": size,
            "frames": len(rows), "dropped": 0, "start_ns": rows[0].stamp_ns, "end_ns": rows[-1].stamp_ns,
            "preprocess": config.as_dict()}
    return FrameSet(frames, labels, np.zeros(len(rows), np.int32), meta)


def folder_to_bag(folder: Path | str, out: Path | str, *, storage: str = "auto",
                  compression: str | None = None, image_topic: str | None = None,
                  command_topic: str | None = None) -> int:
    """Write a dataset folder as a bag; returns the number of frames written."""
    rows = read_rows(folder)
    options = {"command_topic": command_topic} if command_topic is not None else {}
    writer = BagWriter(out, storage=storage, compression=compression, image_topic=image_topic, **options)
    try:
        with writer as bag:
            for row in rows:
                bag.command(row.stamp_ns, row.v, row.w)
                bag.image(row.stamp_ns, load_image(row.image))
    except BaseException:
        shutil.rmtree(out, ignore_errors=True) if Path(out).is_dir() else Path(out).unlink(missing_ok=True)
        raise
    return len(rows)
