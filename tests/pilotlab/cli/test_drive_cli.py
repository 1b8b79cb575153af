"""`pilotlab drive`, through the real command line."""
import json

import pytest

from pilotlab.cli import main


def test_drive_a_reference_brain_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["drive", "--brain", "expert", "--circuit", "simple_circuit", "--timeout", "2", "--timing",
                 "lockstep", "--hardware", "cpu1", "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["brain"] == "expert" and result["timing"] == "lockstep" and result["hardware"]["threads"] == 1
    assert result["brain_frequency_sim_hz"] == 20.0 and (out / "trajectory.png").is_file()
    assert "position_deviation_mae_m" in capsys.readouterr().out


def test_a_reference_brain_replayed_reports_no_inference_time_as_its_lap_job_does(tmp_path, capsys):
    """outside test: `drive --brain explicit` wrote mean_inference_ms 0 where the online job writes none."""
    out = tmp_path / "run"
    assert main(["drive", "--brain", "explicit", "--circuit", "simple_circuit", "--timeout", "2", "--hardware", "cpu1",
                 "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["timing"] == "replay" and result["latency_source"].startswith("none: a reference brain")
    assert result["mean_inference_ms"] is None and result["bm_mean_inference_ms"] is None
    assert result["runs"][0]["mean_inference_ms"] is None and result["measured_inference_ms"] >= 0
    shown = capsys.readouterr().out
    assert "mean_inference_ms" not in shown and "None" not in shown and "position_deviation_mae_m" in shown


def test_drive_names_a_missing_artifact(tmp_path, capsys):
    assert main(["drive", "--artifact", str(tmp_path / "nope"), "--circuit", "simple_circuit",
                 "--out", str(tmp_path / "run")]) == 2
    assert "no such folder" in capsys.readouterr().err


def test_drive_refuses_a_used_out_path_and_meaningless_numbers_before_starting(tmp_path, capsys):
    base = ["drive", "--brain", "expert", "--circuit", "simple_circuit"]
    (tmp_path / "file.bag").write_bytes(b"x")
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "result.json").write_text("{}")
    for extra, message in ((["--out", str(tmp_path / "file.bag")], "is a file"),
                           (["--out", str(tmp_path / "used")], "is a folder that is not empty"),
                           (["--out", str(tmp_path / "a"), "--laps", "0"], "--laps: Input should be greater than 0"),
                           (["--out", str(tmp_path / "a"), "--laps", "nan"], "--laps: Input should be a finite number"),
                           (["--out", str(tmp_path / "a"), "--repetitions", "0"],
                            "--repetitions: Input should be greater than or equal to 1"),
                           (["--out", str(tmp_path / "a"), "--control-hz", "0"], "--control-hz: Input should be greater"),
                           (["--out", str(tmp_path / "a"), "--extra-latency-ms", "-5"],
                            "--extra-latency-ms: Input should be greater than or equal to 0")):
        assert main(base + extra) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "a").exists()


def test_drive_replays_a_latency_file(tmp_path):
    timings = tmp_path / "device.csv"
    timings.write_text("strategy,latency_ms\nexpert,120\n,3\n")
    out = tmp_path / "run"
    assert main(["drive", "--brain", "expert", "--circuit", "simple_circuit", "--timeout", "2", "--hardware", "cpu1",
                 "--latency-file", str(timings), "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["timing"] == "replay" and result["mean_inference_ms"] == 120.0
    assert result["latency_source"] == "latency file device.csv" and result["replayed_latency_ms"] == 120.0
    assert result["brain_frequency_sim_hz"] < 9.0


@pytest.mark.parametrize("content, message", [(b"\xff\xfe\x00garbage", "cannot be read"),
                                              (b"latency_ms\n1e9\n", "from 0 to 60000")])
def test_drive_refuses_a_latency_file_it_cannot_replay_in_one_line(tmp_path, capsys, content, message):
    """Outside test: a latency file that is not text ended `drive` in a UnicodeDecodeError traceback; one
    with a sample of 1e9 ms drove a lap for hours (the lap's timeout cannot cut one iteration)."""
    timings = tmp_path / "device.csv"
    timings.write_bytes(content)
    assert main(["drive", "--brain", "expert", "--circuit", "simple_circuit", "--latency-file", str(timings),
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and "device.csv" in err and len(err.strip().splitlines()) == 1


def test_drive_an_artifact_s_file_names_its_folder(tmp_path, capsys):
    """Outside test: `--artifact exp/model.onnx` said "no such folder" of a file that is there."""
    (tmp_path / "exp").mkdir()
    (tmp_path / "exp" / "model.onnx").write_bytes(b"onnx")
    assert main(["drive", "--artifact", str(tmp_path / "exp" / "model.onnx"), "--circuit", "simple_circuit",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert f"a file; give the artifact's folder ({tmp_path / 'exp'}" in err and len(err.strip().splitlines()) == 1


def test_a_tolerance_on_top_of_an_extra_latency_says_so(tmp_path, capsys):
    """outside test: `--extra-latency-ms 100 --tolerance` printed a tolerance of 50 for a lap completed at +100:
    the search's laps all carry the extra latency, which nothing said."""
    out = tmp_path / "run"
    assert main(["drive", "--brain", "expert", "--circuit", "simple_circuit", "--laps", "0.2", "--extra-latency-ms", "50",
                 "--tolerance", "--out", str(out)]) == 0
    tolerance = json.loads((out / "result.json").read_text())["latency_tolerance_ms"]
    shown = " ".join(capsys.readouterr().out.split())
    assert f"on top of --extra-latency-ms 50: the lap is still completed with {50 + tolerance:g} ms injected in all" in shown
    assert f"latency_tolerance_ms {tolerance:g}" in shown and "termination lap_completed after" in shown


def test_the_tolerance_is_said_when_the_lap_is_lost_at_once_or_never():
    """Outside test: a lap lost with nothing injected printed no tolerance line (null in result.json), and a
    tolerance never lost in the searched range printed no "≥"."""
    from pilotlab.cli.drive import tolerance_said
    assert tolerance_said({"latency_tolerance_ms": None}, 1000) == "none: the lap is lost with nothing injected"
    assert tolerance_said({"latency_tolerance_ms": 1000.0, "tolerance_at_least": True}, 1000).startswith("≥ 1000")
    assert tolerance_said({"latency_tolerance_ms": 70.0}, 1000) == "70"


def test_verbose_shows_the_frames_of_a_brain_that_failed(tmp_path, capsys, monkeypatch):
    """Outside test: `-v` printed pilotlab's frames only; the brain's and its helper module's were cut."""
    (tmp_path / "helper.py").write_text("def compute(d):\n    return d['w']\n")
    (tmp_path / "deep.py").write_text("import helper\n\n\nclass Brain:\n    def act(self, image):\n"
                                      "        return helper.compute({})\n")
    monkeypatch.chdir(tmp_path)
    argv = ["drive", "--brain", "deep.py:Brain", "--circuit", "simple_circuit"]
    assert main(argv + ["--out", "a"]) == 2
    assert capsys.readouterr().err.strip().endswith("helper.py:2: KeyError: 'w' (in deep.py:Brain.act)")
    assert main(["-v", *argv, "--out", "b"]) == 2
    err = capsys.readouterr().err
    assert 'deep.py", line 6, in act' in err and 'helper.py", line 2, in compute' in err


def test_a_brain_that_calls_exit_is_said_at_its_line(tmp_path, capsys, monkeypatch):
    """Outside test: sys.exit(3) in act() was said as "a module that parses the command line or exits when
    imported", with no file or line."""
    (tmp_path / "quit.py").write_text("import sys\n\n\nclass Quit:\n    def act(self, image):\n        sys.exit(3)\n")
    monkeypatch.chdir(tmp_path)
    assert main(["drive", "--brain", "quit.py:Quit", "--circuit", "simple_circuit", "--out", "a"]) == 2
    assert "quit.py:6: code of yours called exit(3) while it ran" in capsys.readouterr().err
