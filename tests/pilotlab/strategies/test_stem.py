"""Stem subsampling (pilotlab.strategies.stem): the first convolutions at twice their stride, each next one at
its even taps, the same function as the network with those taps zeroed, and fewer multiply-accumulates."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from torch import nn

from matrix.kinds import NotApplicable
from pilotlab.errors import PilotlabError
from pilotlab.export import export_artifact
from pilotlab.models.registry import build_model
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy
from pilotlab.strategies.channels import multiply_accumulates
from pilotlab.strategies.common import conv_linear_layers
from pilotlab.strategies.stem import subsample_stem

SHAPE = (1, 3, 66, 200)


def _pilotnet() -> nn.Module:
    torch.manual_seed(0)
    return build_model("pilotnet").eval()


def _odd_taps_zeroed(model: nn.Module, layers: list[str]) -> nn.Module:
    zeroed = copy.deepcopy(model)
    for name in layers:
        weight = zeroed.get_submodule(name).weight
        with torch.no_grad():
            kept = weight[:, :, ::2, ::2].clone()
            weight.zero_()
            weight[:, :, ::2, ::2] = kept
    return zeroed


@pytest.mark.parametrize("convolutions, followers", [(1, ["features.2"]), (2, ["features.2", "features.4"])])
def test_it_computes_what_the_tap_pruned_network_does(convolutions, followers):
    model = _pilotnet()
    expected_network = _odd_taps_zeroed(model, followers)
    taps = subsample_stem(model, SHAPE, convolutions)
    assert taps == [[3, 3]] * convolutions
    strides = [m.stride for _, m in conv_linear_layers(model)[:3]]
    assert strides == ([(4, 4), (1, 1), (2, 2)] if convolutions == 1 else [(4, 4), (2, 2), (1, 1)])
    images = torch.rand(4, *SHAPE[1:])
    with torch.no_grad():
        torch.testing.assert_close(model(images), expected_network(images), rtol=1e-4, atol=1e-5)


def test_it_cuts_the_stems_work():
    model = _pilotnet()
    before = multiply_accumulates(model, SHAPE)
    subsample_stem(model, SHAPE, 1)
    once = multiply_accumulates(model, SHAPE)
    subsampled_twice = _pilotnet()
    subsample_stem(subsampled_twice, SHAPE, 2)
    # conv1 5.5 M -> 1.4 M, conv2 14.2 M -> 5.1 M (9 of 25 taps); twice: conv2 -> 1.3 M, conv3 4.8 M -> 1.7 M
    assert before - once == pytest.approx(13.2e6, rel=0.02)
    assert once - multiply_accumulates(subsampled_twice, SHAPE) == pytest.approx(6.9e6, rel=0.02)


def test_where_it_does_not_hold_it_is_not_applicable():
    padded = nn.Sequential(nn.Conv2d(3, 8, 5, 2, padding=2), nn.ReLU(), nn.Conv2d(8, 8, 5, 2), nn.ReLU(),
                           nn.Flatten(), nn.Linear(8 * 14 * 47, 2))
    with pytest.raises(NotApplicable, match="padding"):
        subsample_stem(padded, SHAPE)
    unit_stride = nn.Sequential(nn.Conv2d(3, 8, 5, 2), nn.ReLU(), nn.Conv2d(8, 8, 3, 1), nn.ReLU(),
                                nn.Flatten(), nn.Linear(8 * 29 * 96, 2))
    with pytest.raises(NotApplicable, match="stride 2 and an odd kernel"):
        subsample_stem(unit_stride, SHAPE)
    with pytest.raises(NotApplicable, match="first 6 layers are convolutions"):
        subsample_stem(_pilotnet(), SHAPE, 5)


def test_any_image_size_keeps_its_shape():
    for height, width in ((66, 200), (67, 67), (70, 71), (81, 100)):
        model = nn.Sequential(nn.Conv2d(3, 8, 5, 2), nn.ReLU(), nn.Conv2d(8, 8, 5, 2), nn.ReLU(), nn.Flatten())
        reference = _odd_taps_zeroed(model, ["2"])
        subsample_stem(model, (1, 3, height, width), 1)
        images = torch.rand(2, 3, height, width)
        with torch.no_grad():
            torch.testing.assert_close(model(images), reference(images), rtol=1e-4, atol=1e-5)


def test_its_onnx_file_runs_with_onnx_runtime_alone_through_the_export(trained, frames, tmp_path, monkeypatch):
    options = {"finetune_epochs": 0, "format": "onnx", "subsample_stem": 2}
    result = apply_strategy("structured_prune", options, StrategySource(trained / "model.pt", tmp_path / "stem", (frames,)))
    plain = apply_strategy("structured_prune", {"finetune_epochs": 0, "format": "onnx"},
                           StrategySource(trained / "model.pt", tmp_path / "plain", (frames,)))
    assert result["stem_taps"] == [[3, 3], [3, 3]]
    assert result["macs"] < 0.6 * plain["macs"]
    out = export_artifact(tmp_path / "stem", result, tmp_path / "deploy")
    code = (out / "README.md").read_text().split("## Load and run")[1].split("```python")[1].split("```")[0]
    assert "import pilotlab" not in code
    namespace = {"images": np.random.default_rng(0).random((4, 3, 66, 200), dtype=np.float32)}
    monkeypatch.chdir(out)
    exec(code, namespace)               # the README's own code, as a user would paste it
    np.testing.assert_allclose(namespace["vw"], load_predictor(out, "cpu1").predict(namespace["images"]), atol=1e-6)


def test_a_negative_count_says_what_is_wrong(trained, tmp_path):
    with pytest.raises(PilotlabError, match="subsample_stem"):
        apply_strategy("structured_prune_int8", {"subsample_stem": -1}, StrategySource(trained / "model.pt", tmp_path))
