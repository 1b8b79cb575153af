"""structured_prune_int8: channels removed (in whole 8-channel blocks) AND int8, with the pruned
network's function kept through quantization."""
from __future__ import annotations

import numpy as np
import onnx
import pytest

from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy
from pilotlab.strategies.channels import kept_count


def test_kept_counts_round_to_whole_blocks():
    assert [kept_count(n, 0.3, 8) for n in (24, 36, 48, 64, 1164, 100, 10)] == [16, 24, 32, 48, 816, 72, 8]
    assert [kept_count(n, 0.3) for n in (24, 36, 48, 64)] == [17, 25, 34, 45]
    assert kept_count(5, 0.3, 8) == 4          # a layer narrower than a block keeps its exact count
    assert kept_count(24, 0.9, 8) == 8         # never below one block
    assert kept_count(12, 0.1, 8) == 12        # never above the original


def test_it_is_pruned_and_quantized(artifacts):
    folder, result = artifacts["structured_prune_int8"]
    assert result["macs"] < 0.55 * result["macs_before"] and result["params"] < 0.55 * result["params_before"]
    assert all(kept % 8 == 0 for kept in result["kept_channels"].values())
    model = onnx.load(str(folder / "model.onnx"))
    weights = [t for t in model.graph.initializer if len(t.dims) >= 2]
    assert sum(t.data_type == onnx.TensorProto.INT8 for t in weights) >= 8    # all but the first conv
    assert result["size_mb"] < 0.3 * artifacts["structured_prune"][1]["size_mb"]


def test_quantization_keeps_the_pruned_function(trained, frames, test_frames, tmp_path):
    options = {"finetune_epochs": 0, "calibration_frames": 48}
    pruned = apply_strategy("structured_prune", {"finetune_epochs": 0, "format": "onnx"},
                            StrategySource(trained / "model.pt", tmp_path / "fp32", (frames,)))
    quantized = apply_strategy("structured_prune_int8", options,
                               StrategySource(trained / "model.pt", tmp_path / "int8", (frames,)))
    assert quantized["kept_channels"] == pruned["kept_channels"]
    batch = np.ascontiguousarray(FrameSet.load(test_frames).inputs(np.arange(8)).numpy())
    expected = load_predictor(tmp_path / "fp32", "cpu1").predict(batch)
    np.testing.assert_allclose(load_predictor(tmp_path / "int8", "cpu1").predict(batch), expected, atol=0.02)


def test_bad_options_say_what_is_wrong(trained, tmp_path):
    with pytest.raises(PilotlabError, match="multiple_of"):
        apply_strategy("structured_prune_int8", {"multiple_of": 0}, StrategySource(trained / "model.pt", tmp_path))
    with pytest.raises(PilotlabError, match="amount"):
        apply_strategy("structured_prune_int8", {"amount": 1.5}, StrategySource(trained / "model.pt", tmp_path))
