"""DeepLearningStudio dataset folders: read directly, and converted to bags that read back the same."""
import cv2
import numpy as np
import pytest

from pilotlab.data.bags import read_bag, read_frames
from pilotlab.data.folder import folder_to_bag, read_folder
from pilotlab.data.preprocess import PreprocessConfig, preprocess
from pilotlab.errors import BagError
from tests.pilotlab.data.bagfiles import images

CONFIG = PreprocessConfig()


def make_folder(folder, frames, header="image_name,v,w,timestamp", rows=None):
    folder.mkdir()
    lines = [header]
    for i, rgb in enumerate(frames):
        cv2.imwrite(str(folder / f"{i}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        lines.append(f"{i}.png,{5 + i * 0.5},{0.1 * i - 0.2},{1650000000 + i * 0.05:.3f}")
    (folder / "data.csv").write_text("\n".join(rows or lines) + "\n")
    return folder


def test_reads_a_folder_directly(tmp_path):
    frames = images(4)
    data = read_frames(make_folder(tmp_path / "dls", frames), CONFIG)
    np.testing.assert_array_equal(data.frames, np.stack([preprocess(f, CONFIG) for f in frames]))
    np.testing.assert_allclose(data.labels, [[5 + i * 0.5, 0.1 * i - 0.2] for i in range(4)], rtol=1e-6)
    assert data.meta["format"] == "folder" and data.meta["image_size"] == [60, 80]


@pytest.mark.parametrize("out, storage", [("run.bag", "auto"), ("run_ros2", "auto"), ("run_mcap", "mcap")])
def test_converted_bags_read_back_the_same_frames_and_labels(tmp_path, out, storage):
    folder = make_folder(tmp_path / "dls", images(5))
    assert folder_to_bag(folder, tmp_path / out, storage=storage) == 5
    direct, converted = read_folder(folder, CONFIG), read_bag(tmp_path / out, CONFIG)
    np.testing.assert_array_equal(converted.frames, direct.frames)
    np.testing.assert_array_equal(converted.labels, direct.labels)
    assert converted.meta["start_ns"] == direct.meta["start_ns"] == 1650000000 * 10**9


def test_without_timestamps_rows_are_20_hz_and_names_default_to_the_row_number(tmp_path):
    folder = make_folder(tmp_path / "dls", images(3), rows=["v,w", "1,0", "2,0.5", "3,-0.5"])
    data = read_folder(folder, CONFIG)
    assert data.meta["end_ns"] - data.meta["start_ns"] == 100_000_000
    np.testing.assert_allclose(data.labels[:, 1], [0, 0.5, -0.5])


def test_folder_errors_say_where_and_what_to_do(tmp_path):
    folder = make_folder(tmp_path / "dls", images(2), rows=["image_name,v,w", "0.png,1,0", "7.png,1,0"])
    with pytest.raises(BagError) as caught:
        read_folder(folder, CONFIG)
    assert str(caught.value) == (f"{folder}/data.csv: row 2 names image '7.png', which is not in {folder}; "
                                 "add the image or remove the row")
    (folder / "data.csv").write_text("image_name,v,w,timestamp\n0.png,1,0,2.0\n1.png,1,0,1.0\n")
    with pytest.raises(BagError) as caught:
        read_folder(folder, CONFIG)
    assert str(caught.value) == (f"{folder}/data.csv: timestamp does not increase at row 2; sort the rows by "
                                 "time, or remove the timestamp column to assume 20 frames per second")
    (folder / "data.csv").write_text("image_name,speed\n0.png,1\n")
    with pytest.raises(BagError) as caught:
        read_folder(folder, CONFIG)
    assert str(caught.value) == (f"{folder}/data.csv: needs a header with columns v and w (and image_name, "
                                 "timestamp) and at least one row; found columns: image_name, speed")
    (folder / "data.csv").write_text("image_name,v,w,timestamp\n")     # outside test: read as "found columns: none"
    with pytest.raises(BagError, match=r"data.csv: holds no rows \(a dataset folder needs a header"):
        read_folder(folder, CONFIG)
    (folder / "data.csv").write_text("image_name,v,w\n0.png,fast,0\n")
    with pytest.raises(BagError, match="row 1, column 'v' is 'fast', not a number; fix the row"):
        read_folder(folder, CONFIG)


@pytest.mark.parametrize("name", ["../outside.png", "{outside}", "linked/outside.png"])
def test_an_image_outside_the_folder_is_refused(tmp_path, name):
    """Only the folder's own files are hashed into the job key: an image read from elsewhere could
    change without the frames going stale."""
    folder = make_folder(tmp_path / "dls", images(2))
    (tmp_path / "outside.png").write_bytes((folder / "1.png").read_bytes())
    (folder / "linked").symlink_to(tmp_path, target_is_directory=True)   # a link to a folder is not followed
    name = name.format(outside=tmp_path / "outside.png")
    (folder / "data.csv").write_text(f"image_name,v,w\n0.png,1,0\n{name},1,0\n")
    with pytest.raises(BagError) as caught:
        read_folder(folder, CONFIG)
    shown = name[:80]   # a long name is cut (a temporary folder's path can be longer)
    assert str(caught.value).startswith(f"{folder}/data.csv: row 2 names image '{shown}', outside {folder}; ")


def test_an_image_linked_to_a_system_file_is_refused(tmp_path):
    folder = make_folder(tmp_path / "dls", images(2))
    (folder / "1.png").unlink()
    (folder / "1.png").symlink_to("/proc/self/environ")
    with pytest.raises(BagError, match=r"data.csv: .*/1.png is a link to /proc/\S+, a system file \(below /proc\)"):
        read_folder(folder, CONFIG)


def test_an_image_in_a_subfolder_or_linked_as_a_file_is_read(tmp_path):
    folder = make_folder(tmp_path / "dls", images(2))
    (folder / "sub").mkdir()
    (folder / "1.png").rename(folder / "sub/1.png")
    (tmp_path / "elsewhere.png").write_bytes((folder / "0.png").read_bytes())
    (folder / "0.png").unlink()
    (folder / "0.png").symlink_to(tmp_path / "elsewhere.png")          # its content is hashed with the folder
    (folder / "data.csv").write_text("image_name,v,w\n0.png,1,0\nsub/1.png,1,0\n")
    assert len(read_folder(folder, CONFIG)) == 2


def test_a_failed_conversion_leaves_no_partial_bag(tmp_path):
    folder = make_folder(tmp_path / "dls", images(2))
    (folder / "1.png").write_bytes(b"broken")
    with pytest.raises(BagError, match="1.png: not a readable image"):
        folder_to_bag(folder, tmp_path / "out.bag")
    assert not (tmp_path / "out.bag").exists()


def rows_with(cell: str, column: int, row: int = 2, n: int = 4) -> list[str]:
    lines = ["image_name,v,w,timestamp"] + [f"{i}.png,{5 + i * 0.5},{0.1 * i - 0.2},{1650000000 + i * 0.05:.3f}"
                                            for i in range(n)]
    fields = lines[row].split(",")
    fields[column] = cell
    lines[row] = ",".join(fields)
    return lines


@pytest.mark.parametrize("cell, column, message", [
    ("nan", 1, r"data.csv: row 2, column 'v' is 'nan'; it must be a finite number within ±1000. Fix or remove the row"),
    ("inf", 2, r"data.csv: row 2, column 'w' is 'inf'; it must be a finite number"),
    ("1e300", 3, r"data.csv: row 2, column 'timestamp' is '1e300'; it must be seconds in \[0, 2\^32\)"),
    ("nan", 3, r"data.csv: row 2, column 'timestamp' is 'nan'; it must be seconds"),
    ("-5", 3, r"data.csv: row 2, column 'timestamp' is '-5'; it must be seconds"),
    ("x" * 5000, 0, r"data.csv: row 2 names image 'xxxx"),
])
def test_labels_and_times_must_be_finite(tmp_path, cell, column, message):
    folder = make_folder(tmp_path / "dls", images(4), rows=rows_with(cell, column))
    with pytest.raises(BagError, match=message) as caught:
        read_frames(folder, CONFIG)
    assert len(str(caught.value)) < 400


@pytest.mark.parametrize("content, message", [
    (b"image_name,v,w\n0.png,1,0\n" + bytes(range(128, 256)), r"data.csv: line 3 is not UTF-8 text \(byte 0x80\)"),
    (b"\xff\xfe" + __import__("random").Random(1).randbytes(3000), r"data.csv: line 1 is not UTF-8 text \(byte 0xff\)"),
])
def test_a_data_csv_that_is_not_text_says_where(tmp_path, content, message):
    folder = make_folder(tmp_path / "dls", images(1))
    (folder / "data.csv").write_bytes(content)
    with pytest.raises(BagError, match=message):
        read_frames(folder, CONFIG)
