"""The TF-MOT rows on LiteRT (pilotlab/strategies/mot.py): what each keeps in the .tflite it writes
(zeros and distinct weight values per layer, read back from the file with the LiteRT interpreter),
and that the exported artifact runs with the runtime alone (the export README's own code)."""
from __future__ import annotations

import numpy as np
import pytest

from pilotlab.export import export_artifact
from pilotlab.predictor import load_predictor
from tests.pilotlab.strategies.test_strategies import runnable

NEW = ["prune_litert", "prune_litert_int8"]
LAYERS = 10                  # PilotNet: 5 convs, 5 dense layers


def tflite_weights(path) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """Each CONV_2D / FULLY_CONNECTED filter of the .tflite, in graph order: its stored values
    (float32, or int8 with per-output-channel scales)."""
    from ai_edge_litert.interpreter import Interpreter
    interpreter = Interpreter(model_path=str(path))
    interpreter.allocate_tensors()
    details = {d["index"]: d for d in interpreter.get_tensor_details()}
    weights = []
    for op in interpreter._get_ops_details():
        if op["op_name"] in ("CONV_2D", "FULLY_CONNECTED"):
            index = op["inputs"][1]
            scales = details[index]["quantization_parameters"]["scales"]
            weights.append((interpreter.get_tensor(index), scales if len(scales) else None))
    return weights


def zeros(weights) -> list[float]:
    return [round(float((w == 0).mean()), 4) for w, _ in weights]


def distinct_per_channel(weights) -> list[int]:
    """The most distinct stored values in one output channel, per layer."""
    return [max(len(np.unique(channel)) for channel in w.reshape(len(w), -1)) for w, _ in weights]


def test_prune_litert_stores_the_zeros_of_every_layer_and_only_compression_shrinks_it(artifacts):
    runnable(artifacts, "prune_litert")
    folder, result = artifacts["prune_litert"]
    weights = tflite_weights(folder / "model.tflite")
    assert len(weights) == LAYERS and all(w.dtype == np.float32 for w, _ in weights)
    assert all(abs(z - 0.5) < 0.01 for z in zeros(weights)), zeros(weights)
    assert result["layer_sparsity"]["features.0"] == pytest.approx(0.5, abs=0.01)
    dense = artifacts["litert"][1]
    assert result["size_mb"] == pytest.approx(dense["size_mb"], rel=0.01)           # zeros are stored
    assert result["size_gz_mb"] < 0.7 * dense["size_gz_mb"], (result["size_gz_mb"], dense["size_gz_mb"])


def test_prune_litert_int8_keeps_the_zeros_through_quantization(artifacts):
    runnable(artifacts, "prune_litert_int8")
    folder, result = artifacts["prune_litert_int8"]
    weights = tflite_weights(folder / "model.tflite")
    assert len(weights) == LAYERS and all(w.dtype == np.int8 and s is not None for w, s in weights)
    # symmetric int8 maps 0.0 to 0; weights below half a step become zero too (a few per cent)
    assert all(0.49 < z < 0.56 for z in zeros(weights)), zeros(weights)
    assert result["size_gz_mb"] < 0.85 * artifacts["litert_int8"][1]["size_gz_mb"]


@pytest.mark.parametrize("name", NEW)
def test_the_exported_artifact_runs_with_the_runtime_alone(name, artifacts, tmp_path, monkeypatch):
    """The README's own "Load and run" code (the LiteRT interpreter, no pilotlab, no TensorFlow)
    gives what pilotlab's predictor gives."""
    runnable(artifacts, name)
    folder, value = artifacts[name]
    out = export_artifact(folder, value, tmp_path / "deploy")
    code = (out / "README.md").read_text().split("## Load and run")[1].split("```python")[1].split("```")[0]
    images = np.random.default_rng(0).random((5, 3, 66, 200), dtype=np.float32)
    namespace = {"images": images}
    monkeypatch.chdir(out)
    exec(code, namespace)
    np.testing.assert_allclose(namespace["vw"], load_predictor(out, "cpu1").predict(images), atol=1e-6)
