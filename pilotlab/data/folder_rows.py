"""A DeepLearningStudio dataset folder's index: `data.csv` (image_name, v, w, timestamp), its rows
checked, and the files a reader of the folder reads (what the folder's job key hashes).

Light (no numpy, OpenCV or torch), so planning can list a folder's files; the images themselves are
read by pilotlab.data.folder.
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from matrix.inputhash import system_root
from pilotlab.data.damage import MAX_COMMAND
from pilotlab.errors import BagError

CSV_NAME = "data.csv"
MAX_SECONDS = 2.0 ** 32        # ROS time stamps are unsigned 32-bit seconds
DEFAULT_RATE_HZ = 20.0         # frame rate assumed when data.csv has no timestamp column


@dataclass(frozen=True)
class FolderRow:
    image: Path
    v: float
    w: float
    stamp_ns: int


def is_dataset_folder(path: Path) -> bool:
    return Path(path).is_dir() and (Path(path) / CSV_NAME).is_file()


def check_not_system(file: Path, where: Path) -> None:
    """A file under /proc, /sys or /dev (links resolved) is refused: reading one may never end, or leak."""
    target = file.resolve()
    if root := system_root(target):
        raise BagError(f"{where}: {file} is {'a link to ' + str(target) + ', ' if target != file else ''}"
                       f"a system file (below {root}), not data; remove it")


def _image_path(folder: Path, name: str, row: int) -> Path:
    try:
        path = folder / name
        if not path.suffix and not path.exists():
            path = path.with_suffix(".png")
        present = path.is_file()
    except (OSError, ValueError):   # too long a name, a NUL byte
        present = False
    if not present:
        raise BagError(f"{folder / CSV_NAME}: row {row} names image {name[:80]!r}, which is not in {folder}; "
                       "add the image or remove the row")
    check_not_system(path, folder / CSV_NAME)
    if not path.parent.resolve().is_relative_to(folder.resolve()):   # not hashed with the folder: not in the key
        raise BagError(f"{folder / CSV_NAME}: row {row} names image {name[:80]!r}, outside {folder}; a dataset "
                       "folder holds its images: copy the image into it and name it relative to the folder")
    return path


def _float(value: str, column: str, row: int, csv_path: Path) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise BagError(f"{csv_path}: row {row}, column {column!r} is {str(value)[:40]!r}, not a number; "
                       "fix the row") from None
    limit = MAX_SECONDS if column == "timestamp" else MAX_COMMAND
    if not (abs(number) <= limit and (column != "timestamp" or number >= 0)):   # also false for NaN
        what = "seconds in [0, 2^32)" if column == "timestamp" else f"a finite number within ±{limit:g}"
        raise BagError(f"{csv_path}: row {row}, column {column!r} is {str(value)[:40]!r}; it must be {what}. "
                       "Fix or remove the row (rows with missing labels are not dropped silently)")
    return number


def _table(csv_path: Path) -> list[dict]:
    """The rows of data.csv, as text: a file that is not UTF-8 text or not CSV is an error naming its line."""
    data = csv_path.read_bytes()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise BagError(f"{csv_path}: line {line} is not UTF-8 text (byte {data[error.start]:#04x}); "
                       f"{CSV_NAME} is a CSV file with columns image_name, v, w, timestamp") from None
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        return list(reader)
    except csv.Error as error:
        raise BagError(f"{csv_path}: line {reader.line_num} is not CSV ({error}); "
                       f"{CSV_NAME} has columns image_name, v, w, timestamp") from None


def read_rows(folder: Path | str, rate_hz: float = DEFAULT_RATE_HZ) -> list[FolderRow]:
    """The rows of a dataset folder, checked: images present, labels finite numbers, time increasing.
    A row whose v or w is not a finite number (NaN, inf, empty) is an error naming the row: a DLS
    export with missing labels is broken, and dropping its rows silently would hide that."""
    folder = Path(folder)
    csv_path = folder / CSV_NAME
    if not csv_path.is_file():
        raise BagError(f"{folder}: not a dataset folder (no {CSV_NAME} with columns image_name, v, w, timestamp)")
    table = _table(csv_path)
    if not table:          # a header alone (or nothing): "found columns: none" read as a wrong header
        raise BagError(f"{csv_path}: holds no rows (a dataset folder needs a header with columns image_name, v, "
                       "w, timestamp, then a row per image)")
    columns = set(table[0])
    if not {"v", "w"} <= columns:
        found = ", ".join(sorted(str(c)[:40] for c in columns if c is not None))[:200]
        raise BagError(f"{csv_path}: needs a header with columns v and w (and image_name, timestamp) "
                       f"and at least one row; found columns: {found or 'none'}")
    rows = []
    for i, entry in enumerate(table, start=1):
        name = entry.get("image_name") or f"{i - 1}.png"
        seconds = (_float(entry["timestamp"], "timestamp", i, csv_path) if "timestamp" in columns
                   else (i - 1) / rate_hz)
        rows.append(FolderRow(_image_path(folder, name, i), _float(entry["v"], "v", i, csv_path),
                              _float(entry["w"], "w", i, csv_path), round(seconds * 1e9)))
    later = next((i for i in range(1, len(rows)) if rows[i].stamp_ns <= rows[i - 1].stamp_ns), None)
    if later is not None:
        raise BagError(f"{csv_path}: timestamp does not increase at row {later + 1}; sort the rows by time, "
                       f"or remove the timestamp column to assume {rate_hz:g} frames per second")
    return rows


def read_files(folder: Path | str) -> list[Path]:
    """What reading the folder reads: data.csv and each image its rows name (checked as `read_rows`)."""
    return [Path(folder) / CSV_NAME, *(row.image for row in read_rows(folder))]
