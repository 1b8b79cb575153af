"""The TF-MOT rows on LiteRT (pilotlab/strategies/mot.py): what each keeps in the .tflite it writes
(zeros and distinct weight values per layer, read back from the file with the LiteRT interpreter),
and that the exported artifact runs with the runtime alone (the export README's own code)."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from pilotlab.export import export_artifact
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy
from tests.pilotlab.strategies.test_strategies import runnable

NEW = ["prune_litert", "prune_litert_int8", "qat_litert_int8", "pqat_litert_int8", "cqat_litert_int8",
       "pcqat_litert_int8"]
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


def on_int8_grid(weight: torch.Tensor) -> bool:
    """Every output channel's weights are whole multiples of max|w| / 127 (the converter's scale)."""
    steps = weight.flatten(1) / (weight.flatten(1).abs().amax(1, keepdim=True) / 127)
    return bool(torch.allclose(steps, steps.round(), atol=1e-3))


def test_quantization_aware_training_leaves_the_weights_on_the_int8_grid():
    from pilotlab.strategies.mot_torch import add_fake_quant, bake, calibrate, remove_hooks
    torch.manual_seed(0)
    model = nn.Sequential(nn.Conv2d(3, 8, 3), nn.ReLU(), nn.Flatten(), nn.Linear(8 * 6 * 6, 2))
    quant = add_fake_quant(model)
    assert len(quant[1]) == 3                    # the input, the ReLU, the output layer (no ReLU after it)
    images = torch.rand(16, 3, 8, 8)
    calibrate(model, quant, [images])
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
    for _ in range(5):
        optimizer.zero_grad()
        model.train()(images).square().mean().backward()
        optimizer.step()
    remove_hooks(quant)
    bake(model)
    assert on_int8_grid(model[0].weight) and on_int8_grid(model[3].weight)
    assert not on_int8_grid(model[3].weight + 1e-3)


def test_qat_quantizes_the_weights_as_the_converter_does(artifacts, trained, frames, tmp_path):
    """With no fine-tuning, QAT's fake-quantized weights are litert_int8's int8 weights, value for value
    (per output channel; the layouts differ): the torch side trains on the grid the converter uses."""
    runnable(artifacts, "qat_litert_int8")
    apply_strategy("qat_litert_int8", {"qat_epochs": 0, "calibration_frames": 16},
                   StrategySource(trained / "model.pt", tmp_path / "qat0", (frames,)))
    ours, theirs = (tflite_weights(folder / "model.tflite")
                    for folder in (tmp_path / "qat0", artifacts["litert_int8"][0]))
    for (a, scale_a), (b, scale_b) in zip(ours, theirs, strict=True):
        np.testing.assert_allclose(scale_a, scale_b, rtol=1e-5)
        same = np.sort(a.reshape(len(a), -1), axis=1) == np.sort(b.reshape(len(b), -1), axis=1)
        assert same.mean() > 0.999, same.mean()


def test_qat_litert_int8_is_int8_with_its_weights_on_the_grid(artifacts):
    runnable(artifacts, "qat_litert_int8")
    folder, result = artifacts["qat_litert_int8"]
    weights = tflite_weights(folder / "model.tflite")
    assert len(weights) == LAYERS and all(w.dtype == np.int8 and abs(w).max() == 127 for w, _ in weights)
    assert result["size_mb"] == pytest.approx(artifacts["litert_int8"][1]["size_mb"], rel=0.03)
    assert result["sparsity"] < 0.05          # only the weights that round to zero


def tiny() -> nn.Module:
    torch.manual_seed(0)
    return nn.Sequential(nn.Conv2d(3, 8, 3), nn.ReLU(), nn.Flatten(), nn.Linear(8 * 6 * 6, 2))


def train(model: nn.Module, steps: int = 5) -> None:
    images = torch.rand(16, 3, 8, 8)
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
    for _ in range(steps):
        optimizer.zero_grad()
        model.train()(images).square().mean().backward()
        optimizer.step()


def test_pruned_weights_stay_zero_through_quantization_aware_training():
    from pilotlab.strategies.mot_torch import add_fake_quant, add_masks, bake, magnitude_masks, remove_hooks
    model = tiny()
    masks = magnitude_masks(model, 0.5)
    add_masks(model, masks)
    train(model)
    quant = add_fake_quant(model)                  # on top of the mask: PQAT
    train(model)
    remove_hooks(quant)
    bake(model)
    for layer, mask in zip((model[0], model[3]), masks.values()):
        assert bool((layer.weight[mask == 0] == 0).all())        # every pruned weight, and few others
        assert 0.5 <= float((layer.weight == 0).float().mean()) < 0.55
        assert on_int8_grid(layer.weight)


@pytest.mark.parametrize("keep_zeros", [False, True])
def test_clustered_weights_stay_on_their_centroids_through_training(keep_zeros):
    from pilotlab.strategies.mot_torch import add_clusters, add_fake_quant, bake, remove_hooks
    model = tiny()
    zeros_before = None
    if keep_zeros:
        with torch.no_grad():
            for layer in (model[0], model[3]):
                layer.weight[layer.weight.abs() < layer.weight.abs().median()] = 0
        zeros_before = [layer.weight == 0 for layer in (model[0], model[3])]
    add_clusters(model, 8, 20, keep_zeros=keep_zeros)
    train(model)
    assert all(len(layer.weight.unique()) <= 8 for layer in (model[0], model[3]))
    quant = add_fake_quant(model)                  # on top of the clusters: CQAT / PCQAT
    train(model)
    remove_hooks(quant)
    bake(model)
    for i, layer in enumerate((model[0], model[3])):
        assert max(len(channel.unique()) for channel in layer.weight.flatten(1)) <= 8
        if zeros_before:
            assert torch.equal(layer.weight == 0, zeros_before[i])


@pytest.mark.parametrize("name, sparsity, clusters", [("pqat_litert_int8", 0.5, None),
                                                      ("cqat_litert_int8", None, 16),
                                                      ("pcqat_litert_int8", 0.5, 16)])
def test_collaborative_optimizations_keep_zeros_and_clusters_in_the_tflite(name, sparsity, clusters, artifacts):
    """Read back from the .tflite: PQAT keeps the pruned zeros, CQAT at most `clusters` int8 values in
    each output channel, PCQAT both (zero being one of the clusters)."""
    runnable(artifacts, name)
    folder, result = artifacts[name]
    weights = tflite_weights(folder / "model.tflite")
    assert len(weights) == LAYERS and all(w.dtype == np.int8 for w, _ in weights)
    if sparsity:
        assert all(sparsity - 0.01 < z < sparsity + 0.06 for z in zeros(weights)), zeros(weights)
    else:
        assert max(zeros(weights)) < 0.2, zeros(weights)
    if clusters:
        assert max(distinct_per_channel(weights)) <= clusters, distinct_per_channel(weights)
        assert max(result["channel_distinct_weights"].values()) <= clusters
    else:
        assert max(distinct_per_channel(weights)) > 2 * 16      # nothing shares values
    assert result["size_gz_mb"] < 0.85 * artifacts["litert_int8"][1]["size_gz_mb"]


def test_clustering_and_pruning_compress_best_together(artifacts):
    for name in ("pqat_litert_int8", "cqat_litert_int8", "pcqat_litert_int8"):
        runnable(artifacts, name)
    size = {name: artifacts[name][1]["size_gz_mb"] for name in ("litert_int8", "pqat_litert_int8",
                                                               "cqat_litert_int8", "pcqat_litert_int8")}
    assert size["pcqat_litert_int8"] < min(size["pqat_litert_int8"], size["cqat_litert_int8"]), size
    assert max(size.values()) == size["litert_int8"], size


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
