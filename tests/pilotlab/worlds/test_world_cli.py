"""`pilotlab world list | show`, `record --world`, `drive --world`, through the real command line, on the
test-written world."""
from __future__ import annotations

import json

import cv2
import pytest

from pilotlab.cli import main


def test_list_shows_the_worlds_with_their_circuit_sun_and_camera(oval_assets, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "160")      # rich wraps cells to the terminal's width
    assert main(["world", "list", "--assets", str(oval_assets)]) == 0
    out = capsys.readouterr().out
    assert "oval_no_sun" in out and "oval.csv" in out and "0.10 m, 90°, 15 m" in out


def test_a_piped_list_has_a_line_per_world_with_nothing_cut(oval_assets, capsys, monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)      # a pipe: rich would squeeze the table into 80 columns
    assert main(["world", "list", "--assets", str(oval_assets)]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("│")]
    assert len(rows) == 2 and not any("…" in row for row in rows)   # oval, oval_no_sun: one line each, whole


def test_one_broken_world_hides_none_of_the_others(oval_assets, tmp_path, capsys, monkeypatch):
    import shutil
    monkeypatch.setenv("COLUMNS", "160")
    assets = shutil.copytree(oval_assets, tmp_path / "assets")
    world = (assets / "worlds" / "oval.world").read_text()
    (assets / "worlds" / "broken.world").write_text(world.replace("model://oval<", "model://nonexistent<"))
    assert main(["world", "list", "--assets", str(assets)]) == 1
    out = " ".join(capsys.readouterr().out.split())
    assert "oval_no_sun" in out and "0.10 m, 90°, 15 m" in out and "(broken: see below)" in out
    assert "broken: " in out and "nonexistent" in out


def test_show_writes_the_frame_the_view_and_pilotlab_s_own_world(oval_assets, tmp_path, capsys):
    frame, view, own = tmp_path / "f.png", tmp_path / "v.png", tmp_path / "own.png"
    for extra, out in (([], frame), (["--view"], view), (["--own"], own)):
        assert main(["world", "show", "oval", "--assets", str(oval_assets), "--pose", "0,8,0", "-o", str(out),
                     *extra]) == 0
    assert cv2.imread(str(frame)).shape == (480, 640, 3) and cv2.imread(str(view)).shape == (66, 200, 3)
    red = cv2.imread(str(frame))[240:, :, ::-1]
    assert ((red[..., 0] > 150) & (red[..., 1] < 80)).sum() > 1000
    assert cv2.imread(str(own)).shape == (480, 640, 3)
    assert "640×480 camera frame written" in capsys.readouterr().out


def test_show_of_pilotlab_s_own_world_follows_the_renderer(oval_assets, tmp_path):
    """Outside test: `--own --renderer pybullet` wrote the ground renderer's picture, byte for byte."""
    ground, bullet = tmp_path / "ground.png", tmp_path / "bullet.png"
    for renderer, out in (("ground", ground), ("pybullet", bullet)):
        assert main(["world", "show", "oval", "--assets", str(oval_assets), "--pose", "0,8,0", "--own",
                     "--renderer", renderer, "-o", str(out)]) == 0
    first, second = cv2.imread(str(ground)), cv2.imread(str(bullet))
    assert first.shape == second.shape == (480, 640, 3) and not (first == second).all()
    red = second[240:, :, ::-1]
    assert ((red[..., 0] > 150) & (red[..., 1] < 80)).sum() > 1000     # the red line, drawn by pybullet


def test_show_without_a_pose_uses_the_spawn_pose(oval_assets, tmp_path):
    assert main(["world", "show", "oval", "--assets", str(oval_assets), "-o", str(tmp_path / "f.png")]) == 0


def test_a_pose_starting_with_a_minus_is_a_value(oval_assets, tmp_path):
    """Outside test: `--pose -200.8,-90.72,-2.83` (a spawn pose as `world list` prints it) was taken for an
    option: "argument --pose: expected one argument"."""
    assert main(["world", "show", "oval", "--assets", str(oval_assets), "--pose", "-0.5,-8,-1e-3",
                 "-o", str(tmp_path / "f.png")]) == 0
    assert (tmp_path / "f.png").is_file()


def test_a_pose_far_from_the_road_is_rendered_with_a_note(oval_assets, tmp_path, capsys):
    """Outside test: a --pose off the map wrote a frame of sky without a word."""
    assert main(["world", "show", "oval", "--assets", str(oval_assets), "--pose", "0,8,0",
                 "-o", str(tmp_path / "near.png")]) == 0
    assert "note:" not in capsys.readouterr().err
    assert main(["world", "show", "oval", "--assets", str(oval_assets), "--pose", "900,900,0",
                 "-o", str(tmp_path / "far.png")]) == 0
    err = capsys.readouterr().err
    assert (tmp_path / "far.png").is_file() and "m from the road" in err and "spawn pose" in err


@pytest.mark.parametrize("args, message", [
    (["world", "show", "ovl"], "did you mean 'oval'"),
    (["world", "show", "../worlds/oval"], "a world is named by its .world file's stem"),
    (["world", "show", "oval", "-o", "/proc/nope/f.png"], "cannot write"),
    (["record", "--world", "ovl", "--out", "x"], "did you mean 'oval'"),
])
def test_errors_are_one_line(oval_assets, capsys, args, message):
    assert main([*args, "--assets", str(oval_assets)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_record_and_drive_in_a_world(oval_assets, tmp_path, capsys):
    bag = tmp_path / "bag"
    assert main(["record", "--world", "oval", "--assets", str(oval_assets), "--laps", "0.05", "--size", "160x120",
                 "--compressed", "png", "--out", str(bag)]) == 0
    assert "drove the 0.05 lap asked for" in capsys.readouterr().out
    out = tmp_path / "drive"
    assert main(["drive", "--brain", "expert", "--world", "oval", "--assets", str(oval_assets),
                 "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["world"] == "oval" and result["lap_completed"] is True and result["runs"][0]["termination"] == "lap_completed"


def test_an_assets_folder_that_is_not_there_is_said_so(capsys):
    """Outside test: it said the folder "has no worlds/ folder"."""
    assert main(["world", "list", "--assets", "/nonexistent/x"]) == 2
    assert "BehaviorMetrics assets folder /nonexistent/x: no such folder" in capsys.readouterr().err


def test_an_output_under_a_file_says_which_file_is_in_the_way(oval_assets, tmp_path, capsys):
    """Outside test: `-o ex1.py/a.png` said "(File exists)"."""
    (tmp_path / "ex1.py").write_text("")
    assert main(["world", "show", "oval", "--assets", str(oval_assets), "-o", str(tmp_path / "ex1.py" / "a.png")]) == 2
    assert f"({tmp_path / 'ex1.py'} is a file, not a folder)" in capsys.readouterr().err
