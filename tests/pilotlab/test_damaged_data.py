"""Damaged data through the real jobs: tiny real recordings (ROS1, ROS2, ROS2 jpeg), a DLS folder made
from one, and circuit CSVs, damaged in seeded ways, each read by a `frames` (or `record`) job run as
the engine runs it. Each job ends ok with finite numbers, or failed with the domain's own one-line
error; never an unexpected exception, never a NaN reported ok."""
from __future__ import annotations

import random
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from matrix.jobs import Job, input_file
from matrix.store import Store
from matrix.worker import execute_job, non_finite
from pilotlab.data.frames import FrameSet
from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
from pilotlab.jobs import record as record_job  # noqa: F401  (registers "record")
from tests.pilotlab.tracks import stadium, write_csv

KINDS = ["pilotlab.jobs.record", "pilotlab.jobs.frames"]
RECORDINGS = {"ros1": ("ros1", None), "ros2": ("ros2", None), "ros2_jpeg": ("ros2", "jpeg")}


def run_job(store: Path, job: Job) -> tuple[str, dict]:
    """(ok | refused, result or failure) of one job run as a worker runs it."""
    outcome = execute_job(str(store), job.spec(), KINDS)
    if outcome["status"] in ("ok", "done_elsewhere"):   # (an undamaged copy may equal an earlier one)
        return "ok", Store(store).result(job.key)
    failure = Store(store).failure(job.key)
    assert failure["expected"], f"{job.name}: not a pilotlab error:\n{failure['traceback']}"
    assert "\n" not in failure["error"] and len(failure["error"]) < 1000, failure["error"]
    return "refused", failure


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> dict[str, Path]:
    """Tiny real recordings (30 frames each), by the record job, and a DLS folder made from one."""
    root = tmp_path_factory.mktemp("recordings")
    csv = write_csv(root / "stadium.csv", stadium())
    found = {}
    for name, (fmt, compressed) in RECORDINGS.items():
        job = Job("record", f"record {name}", {"circuit": str(csv), "laps": 0.15, "camera": {"width": 64, "height": 48},
                                               "format": fmt, "compressed": compressed},
                  inputs={"circuit_csv": input_file(str(csv))})
        status, result = run_job(root / "store", job)
        assert status == "ok"
        found[name] = Store(root / "store").artifacts(job.key) / result["value"]["bag"]
    found["dls"] = dls_folder(root / "dls", found["ros1"])
    return found


def dls_folder(folder: Path, bag: Path) -> Path:
    """A DeepLearningStudio folder (<n>.png + data.csv) holding the frames and labels of `bag`."""
    from pilotlab.data.bags import read_frames
    from pilotlab.data.preprocess import PreprocessConfig
    frames = read_frames(bag, PreprocessConfig())
    folder.mkdir()
    rows = ["image_name,v,w,timestamp"]
    for i, (image, (v, w)) in enumerate(zip(frames.frames, frames.labels)):
        cv2.imwrite(str(folder / f"{i}.png"), cv2.cvtColor(np.asarray(image), cv2.COLOR_RGB2BGR))
        rows.append(f"{i}.png,{v:.6f},{w:.6f},{1650000000 + 0.1 * i:.3f}")
    (folder / "data.csv").write_text("\n".join(rows) + "\n")
    return folder


# --- damage ----------------------------------------------------------------------------------

def bag_file(path: Path) -> Path:
    return path if path.is_file() else next(f for f in path.iterdir() if f.suffix in (".db3", ".mcap"))


def damage_bag(path: Path, how: str, rng: random.Random) -> None:
    file = bag_file(path)
    data = bytearray(file.read_bytes())
    if how.startswith("flip"):
        for _ in range(int(how[4:])):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    elif how == "cut":
        data = data[:-1 - rng.randrange(200)]
    elif how == "zeros":
        start = rng.randrange(len(data))
        data[start:start + 512] = bytes(len(data[start:start + 512]))
    elif how == "count" and (path / "metadata.yaml").exists():
        metadata = path / "metadata.yaml"
        metadata.write_text(metadata.read_text().replace("message_count: 30", "message_count: 31"))
    file.write_bytes(bytes(data))


def damage_folder(folder: Path, how: str, rng: random.Random) -> None:
    csv = folder / "data.csv"
    lines = csv.read_text().splitlines()
    row = rng.randrange(1, len(lines))
    fields = lines[row].split(",")
    if how == "random_csv":
        csv.write_bytes(rng.randbytes(2000))
    elif how in ("nan_v", "inf_w", "huge_time"):
        column, value = {"nan_v": (1, "nan"), "inf_w": (2, "inf"), "huge_time": (3, "1e300")}[how]
        fields[column] = value
        lines[row] = ",".join(fields)
        csv.write_text("\n".join(lines) + "\n")
    elif how == "flip_csv":
        data = bytearray(csv.read_bytes())
        for _ in range(5):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        csv.write_bytes(bytes(data))
    elif how in ("cut_png", "garbage_png", "missing_png"):
        image = folder / fields[0]
        if how == "cut_png":
            image.write_bytes(image.read_bytes()[:rng.randrange(1, 60)])
        elif how == "garbage_png":
            image.write_bytes(rng.randbytes(300))
        else:
            image.unlink()
    elif how == "swapped_rows":
        lines[1], lines[2] = lines[2], lines[1]
        csv.write_text("\n".join(lines) + "\n")


BAG_DAMAGE = ["flip1", "flip10", "flip100", "cut", "zeros", "count"]
FOLDER_DAMAGE = ["random_csv", "nan_v", "inf_w", "huge_time", "flip_csv", "cut_png", "garbage_png",
                 "missing_png", "swapped_rows"]


def frames_outcome(recordings, tmp_path: Path, source: str, how: str, seed: int) -> str:
    damaged = tmp_path / f"{source}-{how}-{seed}" / recordings[source].name
    copy = shutil.copytree if recordings[source].is_dir() else shutil.copy
    damaged.parent.mkdir()
    copy(recordings[source], damaged)
    rng = random.Random(f"{source} {how} {seed}")
    (damage_folder if source == "dls" else damage_bag)(damaged, how, rng)
    job = Job("frames", f"frames {damaged.parent.name}", {"label": how}, inputs={"bag": input_file(str(damaged))})
    status, record = run_job(tmp_path / "store", job)
    if status == "ok":
        assert non_finite(record["value"]) is None
        saved = FrameSet.load(Store(tmp_path / "store").artifacts(job.key))
        assert len(saved) > 0 and np.isfinite(np.asarray(saved.labels)).all()
    return status


@pytest.mark.parametrize("source", list(RECORDINGS))
@pytest.mark.parametrize("how", BAG_DAMAGE)
def test_a_damaged_bag_is_read_or_refused(recordings, tmp_path, source, how):
    frames_outcome(recordings, tmp_path, source, how, seed=0)


@pytest.mark.parametrize("how", FOLDER_DAMAGE)
def test_a_damaged_dls_folder_is_read_or_refused(recordings, tmp_path, how):
    status = frames_outcome(recordings, tmp_path, "dls", how, seed=0)
    if how != "flip_csv":
        assert status == "refused"


BAD_CIRCUITS = {
    "nan": lambda points: np.where(np.arange(len(points))[:, None] == 7, np.nan, points),
    "1e300": lambda points: np.where(np.arange(len(points))[:, None] == 7, 1e300, points),
    "1e12_scaled": lambda points: points * 1e12,
    "collinear": lambda points: np.stack([points[:, 0], np.zeros(len(points))], axis=1),
    "zigzag": lambda points: np.array([(10.0 * i, 10.0 * (i % 2)) for i in range(12)]),
}


@pytest.mark.parametrize("how", list(BAD_CIRCUITS) + ["binary"])
def test_a_damaged_circuit_csv_is_refused_by_the_record_job(tmp_path, how):
    csv = tmp_path / "bad.csv"
    if how == "binary":
        csv.write_bytes(random.Random(3).randbytes(3000))
    else:
        write_csv(csv, BAD_CIRCUITS[how](stadium()))
    job = Job("record", f"record {how}", {"circuit": str(csv), "laps": 0.1, "camera": {"width": 32, "height": 24}},
              inputs={"circuit_csv": input_file(str(csv))})
    status, failure = run_job(tmp_path / "store", job)
    assert status == "refused" and str(csv) in failure["error"]


@pytest.mark.slow
def test_many_damaged_recordings(recordings, tmp_path):
    outcomes = {}
    for seed in range(1, 16):
        for source in RECORDINGS:
            for how in BAG_DAMAGE:
                status = frames_outcome(recordings, tmp_path, source, how, seed)
                outcomes[status] = outcomes.get(status, 0) + 1
        for how in FOLDER_DAMAGE:
            status = frames_outcome(recordings, tmp_path, "dls", how, seed)
            outcomes[status] = outcomes.get(status, 0) + 1
    print(outcomes)
