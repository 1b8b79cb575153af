"""Artifacts from elsewhere (`drive --artifact`, `export`): a damaged artifact.json, a model file named
outside the folder, an ONNX model whose weights live outside its folder: one-line errors."""
import json

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from pilotlab.cli import main
from pilotlab.errors import PilotlabError
from pilotlab.predictor import load_predictor
from pilotlab.strategies.artifact import ArtifactMeta, read_meta, write_meta


def meta(**changes) -> ArtifactMeta:
    fields = dict(strategy="onnxruntime", strategy_version=1, format="onnx", file="model.onnx",
                  runtime="onnxruntime", dtype="float32", input_shape=(None, 3, 66, 200), arch="pilotnet",
                  config={}, labels={"v": [0.0, 1.0], "w": [-1.0, 1.0]})
    return ArtifactMeta(**{**fields, **changes})


@pytest.mark.parametrize("text, message", [
    ("{not json", "not readable JSON"), ("[1, 2]", "artifact format 'list'"), ("\xff\xfe", "not readable JSON"),
    ('{"artifact_format": "pilotlab-artifact/1"}', "damaged artifact.json"),
    ('{"artifact_format": "pilotlab-artifact/1", "input": 3}', "damaged artifact.json")])
def test_a_damaged_artifact_json_is_one_line(tmp_path, text, message):
    (tmp_path / "artifact.json").write_bytes(text.encode("latin-1"))
    with pytest.raises(PilotlabError, match=message) as error:
        read_meta(tmp_path)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("name", ["../model.onnx", "/etc/passwd", "sub/model.onnx", "", "..", 3])
def test_the_model_file_must_be_a_name_in_the_folder(tmp_path, name):
    data = meta().to_json()
    (tmp_path / "artifact.json").write_text(json.dumps({**data, "file": name}))
    with pytest.raises(PilotlabError, match="is not a file name in the artifact's folder"):
        read_meta(tmp_path)


def onnx_with_external_weights(folder, location):
    """A one-node model (images + bias) whose bias is stored in the external file `location`."""
    bias = numpy_helper.from_array(np.zeros((1, 3, 66, 200), np.float32), "bias")
    bias.ClearField("raw_data")
    bias.data_location = TensorProto.EXTERNAL
    for key, value in (("location", location), ("offset", "0"), ("length", str(3 * 66 * 200 * 4))):
        bias.external_data.add(key=key, value=value)
    graph = helper.make_graph([helper.make_node("Add", ["images", "bias"], ["vw"])], "g",
                              [helper.make_tensor_value_info("images", TensorProto.FLOAT, [None, 3, 66, 200])],
                              [helper.make_tensor_value_info("vw", TensorProto.FLOAT, None)], [bias])
    # IR 9 / opset 17: what every ONNX Runtime pilotlab supports reads (onnx 1.23 writes IR 14 by default,
    # which the GPU machine's ONNX Runtime 1.30 refused)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=9)
    onnx.save(model, str(folder / "model.onnx"))
    write_meta(folder, meta())


@pytest.mark.parametrize("location", ["../outside.bin", "/etc/hostname", "sub/../../outside.bin"])
def test_onnx_weights_outside_the_folder_are_refused(tmp_path, location, capsys):
    (tmp_path / "outside.bin").write_bytes(bytes(3 * 66 * 200 * 4))
    folder = tmp_path / "artifact"
    folder.mkdir()
    onnx_with_external_weights(folder, location)
    with pytest.raises(PilotlabError, match="outside the artifact's folder") as error:
        load_predictor(folder, "cpu")
    assert "\n" not in str(error.value)
    assert main(["drive", "--artifact", str(folder), "--circuit", "simple_circuit",
                 "--out", str(tmp_path / "lap")]) == 2
    err = capsys.readouterr().err
    assert "outside the artifact's folder" in err and len(err.strip().splitlines()) == 1


def test_onnx_weights_inside_the_folder_load(tmp_path):
    (tmp_path / "weights.bin").write_bytes(bytes(3 * 66 * 200 * 4))
    onnx_with_external_weights(tmp_path, "weights.bin")
    batch = np.ones((1, 3, 66, 200), np.float32)
    np.testing.assert_array_equal(load_predictor(tmp_path, "cpu").predict(batch), batch)


def test_a_model_file_that_is_not_onnx_is_one_line(tmp_path):
    (tmp_path / "model.onnx").write_bytes(b"\x00garbage" * 100)
    write_meta(tmp_path, meta())
    with pytest.raises(PilotlabError, match="model.onnx") as error:
        load_predictor(tmp_path, "cpu")
    assert "\n" not in str(error.value)
