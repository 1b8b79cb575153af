"""A checkpoint is plain data: one that would run code when unpickled is refused, never loaded."""
import pytest
import torch

from pilotlab.cli import main
from pilotlab.errors import PilotlabError
from pilotlab.models import build_model, load_checkpoint, make_config, save_checkpoint
from pilotlab.strategies.artifact import ArtifactMeta, write_meta


class Payload:
    """Unpickling this calls open(marker, "w"): a harmless stand-in for any code."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return open, (self.marker, "w")


def hostile_checkpoint(path, marker):
    config = make_config("pilotnet")
    torch.save({"format": "pilotlab-checkpoint/1", "arch": "pilotnet", "config": {},
                "state_dict": build_model("pilotnet", config).state_dict(), "labels": Payload(marker)}, path)
    return path


def test_a_checkpoint_holding_a_pickle_payload_is_refused_without_running_it(tmp_path):
    marker = tmp_path / "ran"
    path = hostile_checkpoint(tmp_path / "model.pt", marker)
    with pytest.raises(PilotlabError) as error:
        load_checkpoint(path)
    assert "refused" in str(error.value) and "\n" not in str(error.value)
    assert not marker.exists()


def test_the_checkpoints_pilotlab_writes_load_as_plain_data(tmp_path):
    import numpy as np
    config = make_config("pilotnet")
    save_checkpoint(tmp_path / "model.pt", build_model("pilotnet", config), "pilotnet", config,
                    labels={"v": (np.float32(2.0), 10.0), "w": [-2.0, 2.0]}, history=[{"loss": np.float64(0.5)}])
    model, checkpoint = load_checkpoint(tmp_path / "model.pt")
    assert checkpoint["labels"]["v"] == [2.0, 10.0] and type(checkpoint["history"][0]["loss"]) is float
    assert torch.load(tmp_path / "model.pt", weights_only=True)["arch"] == "pilotnet"


def test_a_checkpoint_with_other_python_objects_cannot_be_written(tmp_path):
    config = make_config("pilotnet")
    with pytest.raises(PilotlabError, match="plain data only"):
        save_checkpoint(tmp_path / "model.pt", build_model("pilotnet", config), "pilotnet", config,
                        extra=object())


def test_drive_refuses_an_artifact_whose_checkpoint_holds_a_payload(tmp_path, capsys):
    marker, folder = tmp_path / "ran", tmp_path / "artifact"
    folder.mkdir()
    hostile_checkpoint(folder / "model.pt", marker)
    write_meta(folder, ArtifactMeta(strategy="baseline", strategy_version=1, format="pilotlab-checkpoint",
                                    file="model.pt", runtime="torch", dtype="float32",
                                    input_shape=(None, 3, 66, 200), arch="pilotnet", config={},
                                    labels={"v": [0.0, 1.0], "w": [-1.0, 1.0]}))
    assert main(["drive", "--artifact", str(folder), "--circuit", "simple_circuit",
                 "--out", str(tmp_path / "lap")]) == 2
    err = capsys.readouterr().err
    assert "refused" in err and len(err.strip().splitlines()) == 1
    assert not marker.exists()


def test_the_payload_does_run_when_unpickled_without_weights_only(tmp_path):
    """The test's payload is real: a plain torch.load (weights_only=False) runs it."""
    marker = tmp_path / "ran"
    torch.load(hostile_checkpoint(tmp_path / "model.pt", marker), weights_only=False)
    assert marker.exists()
