"""Bag -> preprocessed frames per second, for 640×480 raw rgb8 images (run: -m benchmark -s).

Prints figures and ratios measured in the same run; never asserts timings (the machine is shared).
"""
import os
import shutil
import time

import cv2
import numpy as np
import pytest
from rich.console import Console
from rich.table import Table

from pilotlab.data.bags import read_bag
from pilotlab.data.preprocess import PreprocessConfig
from tests.pilotlab.data.bagfiles import RawBag

FRAMES = int(os.environ.get("PILOTLAB_BENCH_FRAMES", "400"))
TARGET_FPS = 2000


def camera_images(count: int) -> list[np.ndarray]:
    """A few distinct 640×480 road-like images (grey road, red centre line), reused."""
    images = []
    for shift in range(8):
        image = np.full((480, 640, 3), 110, np.uint8)
        image[:240] = (150, 180, 220)
        cv2.line(image, (320 + 20 * shift, 480), (300 + 10 * shift, 240), (220, 30, 30), 6)
        images.append(image)
    return [images[i % len(images)] for i in range(count)]


def write(path, kind, frames, compressed=None):
    with RawBag(path, kind) as bag:
        for i, image in enumerate(frames):
            bag.twist(10**9 + i * 5 * 10**7, 3.0, 0.1)
            if compressed:
                bag.compressed(10**9 + i * 5 * 10**7, image, compressed)
            else:
                bag.image(10**9 + i * 5 * 10**7, image)


def measure(path, config, workers, repeats=3) -> tuple[float, float]:
    """(frames per second, CPU milliseconds per frame over all threads), the best of `repeats`."""
    fps, cpu_ms = 0.0, float("inf")
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        count = len(read_bag(path, config, workers=workers))
        fps = max(fps, count / (time.perf_counter() - wall))
        cpu_ms = min(cpu_ms, (time.process_time() - cpu) / count * 1e3)
    return fps, cpu_ms


@pytest.mark.benchmark
def test_bag_to_frames_per_second(tmp_path):
    cv2.setNumThreads(1)
    frames = camera_images(FRAMES)
    table = Table("bag", "resize", "threads", "frames/s", f"vs {TARGET_FPS}", "CPU ms/frame")
    cores = len(os.sched_getaffinity(0))
    for kind, compressed in [("ros1", None), ("sqlite3", None), ("mcap", None), ("ros1", "jpeg")]:
        path = tmp_path / ("bench.bag" if kind == "ros1" else f"bench_{kind}")
        write(path, kind, frames if not compressed else frames[:FRAMES // 4], compressed)
        read_bag(path, PreprocessConfig(), workers=0)        # page cache warm, as a rerun would be
        for interpolation in ("fast_area", "area", "linear"):
            for workers in (None, 0, 2):
                fps, cpu_ms = measure(path, PreprocessConfig(interpolation=interpolation), workers)
                table.add_row(f"{kind} {compressed or 'rgb8'}", interpolation,
                              "default" if workers is None else str(workers), f"{fps:,.0f}",
                              f"{fps / TARGET_FPS:.2f}×", f"{cpu_ms:.2f}")
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    console = Console(width=120)
    console.print(f"bag -> uint8 66×200 frames, {FRAMES} images 640×480, {cores} cores, load average "
                  f"{os.getloadavg()[0]:.1f} (other work on the machine lowers frames/s, less so CPU ms/frame)")
    console.print(table)
