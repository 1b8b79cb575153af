"""`pilotlab drive`, through the real command line."""
import json

from pilotlab.cli import main


def test_drive_a_reference_brain_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["drive", "--brain", "expert", "--circuit", "simple_circuit", "--timeout", "2", "--timing",
                 "lockstep", "--hardware", "cpu1", "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["brain"] == "expert" and result["timing"] == "lockstep" and result["hardware"]["threads"] == 1
    assert result["brain_frequency_sim_hz"] == 20.0 and (out / "trajectory.png").is_file()
    assert "position_deviation_mae_m" in capsys.readouterr().out


def test_drive_names_a_missing_artifact(tmp_path, capsys):
    assert main(["drive", "--artifact", str(tmp_path / "nope"), "--circuit", "simple_circuit",
                 "--out", str(tmp_path / "run")]) == 2
    assert "no such folder" in capsys.readouterr().err
