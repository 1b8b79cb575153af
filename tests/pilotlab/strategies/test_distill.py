"""Knowledge distillation (`distill`) in the fine-tunes of the pruning and QAT strategies: the
trained baseline's outputs as soft targets beside the labels."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy
from pilotlab.strategies.common import soft_targets


def test_the_distillation_loss_is_the_mse_against_the_blended_target():
    """(1 - a)·MSE(s, y) + a·MSE(s, t) and MSE(s, (1 - a)·y + a·t) differ by a constant: same gradient."""
    generator = torch.Generator().manual_seed(0)
    student, labels, teacher = (torch.rand(32, 2, generator=generator) for _ in range(3))
    student.requires_grad_(True)
    for a in (0.0, 0.3, 1.0):
        mse = torch.nn.functional.mse_loss
        (kd,) = torch.autograd.grad((1 - a) * mse(student, labels) + a * mse(student, teacher), student)
        (blended,) = torch.autograd.grad(mse(student, (1 - a) * labels + a * teacher), student)
        torch.testing.assert_close(kd, blended)


def test_soft_targets_blend_the_labels_with_the_baselines_outputs(trained, frames):
    source = StrategySource(trained / "model.pt", trained / "unused", (frames,))
    data = FrameSet.load(frames)
    with torch.no_grad():
        outputs = source.labels.denormalise(source.load_model().eval()(data.inputs(np.arange(len(data)))).numpy())
    np.testing.assert_allclose(soft_targets(source, 1.0).labels, outputs, rtol=1e-5, atol=1e-5)
    half = soft_targets(source, 0.5)
    np.testing.assert_allclose(half.labels, (np.asarray(data.labels) + outputs) / 2, rtol=1e-5, atol=1e-5)
    assert half.frames is source.calibration.frames             # the images are not copied


def test_distilling_pulls_the_pruned_network_towards_the_baseline(trained, frames, test_frames, tmp_path):
    from tests.pilotlab.strategies.test_strategies import baseline_output, inputs
    batch = inputs(test_frames, 12)
    baseline, distance = baseline_output(trained, batch), {}
    for distill in (0.0, 1.0):
        options = {"finetune_epochs": 10, "batch_size": 16, "distill": distill}   # (torchscript: no ONNX export)
        apply_strategy("structured_prune", options,
                       StrategySource(trained / "model.pt", tmp_path / str(distill), (frames,)))
        predicted = load_predictor(tmp_path / str(distill), "cpu1").predict(batch)
        distance[distill] = float(((predicted - baseline) ** 2).mean())
    assert distance[1.0] < 0.5 * distance[0.0], distance


@pytest.mark.parametrize("name", ["structured_prune", "structured_prune_int8", "structured_prune_litert_int8",
                                  "prune_litert", "prune_litert_int8", "qat_litert_int8", "pqat_litert_int8",
                                  "cqat_litert_int8", "pcqat_litert_int8"])
def test_distill_is_an_option_of_the_pruning_and_qat_fine_tunes_with_a_range(name, trained, tmp_path):
    from pilotlab.strategies import make_strategy_config
    assert make_strategy_config(name, {"distill": 0.5}).distill == 0.5
    with pytest.raises(PilotlabError, match=rf"strategies.{name}: distill: 1.5 is not a weight in \[0, 1\]"):
        make_strategy_config(name, {"distill": 1.5})
