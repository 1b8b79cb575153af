"""Input files: hashed by content, refused when they are not data, remembered across processes."""
import hashlib
import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from matrix.errors import MatrixError
from matrix.fingerprint import clear_caches
from matrix.inputhash import _HashProgress, hash_path
from tests.child import python_path

ROOT = Path(__file__).resolve().parents[2]


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def test_a_folder_hash_keeps_its_format(tmp_path):
    """Keys of stored jobs depend on it: names (sorted by path parts) and contents, as always."""
    (tmp_path / "a").mkdir()
    files = {"a/b": b"1", "a.txt": b"2", "z": b"3"}
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / "link").symlink_to(tmp_path / "z")
    (tmp_path / "dirlink").symlink_to(tmp_path / "a")          # links to folders are not followed
    (tmp_path / "broken").symlink_to(tmp_path / "nowhere")     # nor broken links
    expected = hashlib.sha256()
    for name in ["a/b", "a.txt", "link", "z"]:
        expected.update(f"{name}:{sha((tmp_path / name).read_bytes())}\n".encode())
    assert hash_path(tmp_path) == expected.hexdigest()


@pytest.mark.parametrize("target, message", [
    ("/proc/self/mem", "is a system file (below /proc), not data"),
    ("/dev/zero", "is a system file (below /dev), not data"),
    ("/", "which is a system folder (below /"),
    ("FIFO", "is not a regular file or folder (a pipe)"),
    ("FOLDER_WITH_FIFO", "which is a pipe, not data"),
    ("a" * 5000, "cannot be read: File name too long"),
])
def test_what_is_not_data_is_refused_at_once(tmp_path, target, message):
    if target == "FIFO":
        target = tmp_path / "fifo"
        os.mkfifo(target)
    elif target == "FOLDER_WITH_FIFO":
        os.mkfifo(tmp_path / "pipe")
        target = tmp_path
    started = time.monotonic()
    with pytest.raises(MatrixError) as caught:
        hash_path(target)
    assert message in str(caught.value)
    assert len(str(caught.value)) < 300 and "\n" not in str(caught.value)
    assert time.monotonic() - started < 5


@pytest.mark.parametrize("target", ["/proc/self/environ", "/dev/zero", "/sys/kernel/mm"])
def test_a_link_to_a_system_file_inside_a_folder_is_refused(tmp_path, target):
    """The rule holds for every file hashed (and then read), links resolved, not only for the folder named."""
    (tmp_path / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (tmp_path / "run_0.db3").symlink_to(target)
    with pytest.raises(MatrixError) as caught:
        hash_path(tmp_path)
    message = str(caught.value)
    root = "/" + target.split("/")[1]
    assert f"holds {tmp_path}/run_0.db3, a link to {root}/" in message and f"a system file (below {root})" in message
    assert "\n" not in message


def test_hashing_is_bounded_with_a_clear_error(tmp_path, monkeypatch):
    import matrix.inputhash
    (tmp_path / "a").mkdir()
    for i in range(4):
        (tmp_path / "a" / f"{i}.bin").write_bytes(b"x" * 1000)
    monkeypatch.setenv("MATRIX_MAX_INPUT_GB", "0.000003")     # 3000 bytes
    with pytest.raises(MatrixError, match=r"input .*/a holds 0.0 GB in 4 file\(s\), more than the 3e-06 GB an "
                                          r"input may hold; .* raise the limit with MATRIX_MAX_INPUT_GB"):
        hash_path(tmp_path / "a")
    assert len(hash_path(tmp_path / "a" / "0.bin")) == 64
    for bad in ("lots", "nan", "-1"):       # nan turned the limit off; -1 was read as a limit
        monkeypatch.setenv("MATRIX_MAX_INPUT_GB", bad)
        with pytest.raises(MatrixError, match=f"MATRIX_MAX_INPUT_GB='{bad}' is not a positive number"):
            hash_path(tmp_path / "a" / "0.bin")
    monkeypatch.delenv("MATRIX_MAX_INPUT_GB")
    monkeypatch.setattr(matrix.inputhash, "MAX_INPUT_FILES", 3)
    with pytest.raises(MatrixError, match=r"input folder .*/a holds more than 3 files; name the recording itself"):
        hash_path(tmp_path / "a")


HASH_IN_A_PROCESS = "import sys; from matrix.inputhash import hash_path; print(hash_path(sys.argv[1]))"


def hash_in_a_new_process(path: Path, cache: Path) -> str:
    env = {**os.environ, "MATRIX_HASH_CACHE": str(cache), "PYTHONPATH": python_path(ROOT)}
    return subprocess.run([sys.executable, "-c", HASH_IN_A_PROCESS, str(path)], env=env, check=True,
                          capture_output=True, text=True).stdout.strip()


def test_a_large_input_is_hashed_once_across_processes(tmp_path):
    data = os.urandom(2 << 20)
    bag, cache = tmp_path / "big.bag", tmp_path / "hashes.sqlite"
    bag.write_bytes(data)
    assert hash_in_a_new_process(bag, cache) == sha(data)
    # the next process believes the cache (proof that it does not read the file again) ...
    with sqlite3.connect(cache) as db:
        db.execute("UPDATE hashes SET sha256 = ?", ("f" * 64,))
    assert hash_in_a_new_process(bag, cache) == "f" * 64
    # ... until the file changes (size, mtime or inode)
    stat = bag.stat()
    os.utime(bag, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000))
    assert hash_in_a_new_process(bag, cache) == sha(data)
    replaced = tmp_path / "copy.bag"
    replaced.write_bytes(data[::-1])
    os.utime(replaced, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000))
    replaced.replace(bag)   # same size and mtime, another inode
    assert hash_in_a_new_process(bag, cache) == sha(data[::-1])


def test_an_unusable_cache_only_costs_time(tmp_path, monkeypatch):
    (tmp_path / "cache").write_text("a file where the cache's folder should be")
    monkeypatch.setenv("MATRIX_HASH_CACHE", str(tmp_path / "cache" / "hashes.sqlite"))
    data = os.urandom(2 << 20)
    (tmp_path / "big.bag").write_bytes(data)
    assert hash_in_a_new_process(tmp_path / "big.bag", tmp_path / "cache" / "hashes.sqlite") == sha(data)


def test_long_hashing_prints_a_progress_line(tmp_path, capsys):
    file = tmp_path / "big.bag"
    file.write_bytes(os.urandom(3 << 20))
    with _HashProgress(file, 3 << 20, after_s=0, every_s=0) as progress:
        progress.advance(1 << 20)
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"hashing input {file}: 1.0 MB of 3.1 MB")
    assert err[-1].startswith(f"hashed input {file}: 3.1 MB in")
    clear_caches()
