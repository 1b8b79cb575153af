"""Prepared networks: pruned and fine-tuned once by a prepare job, converted by every strategy that shares them."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from matrix import engine
from matrix.recipe import load_recipe
from pilotlab.data.frames import FrameSet
from pilotlab.domain import DOMAIN
from pilotlab.predictor import load_predictor
from pilotlab.strategies import PREPARATIONS, STRATEGIES
from pilotlab.strategies.apply import StrategySource, apply_strategy
from pilotlab.strategies.prepared import load_prepared, prepare, save_prepared

ROOT = Path(__file__).resolve().parents[3]


def test_strategies_that_convert_the_same_network_share_its_prepare_job():
    """In the study, structured_prune_int8 (ONNX Runtime) and structured_prune_litert_int8 (LiteRT) prune and
    fine-tune with the same options: one prepare job; structured_prune's options differ: its own. The four
    magnitude-pruning rows share theirs, local_prune and prune_quant the L1-pruned network; a strategy that
    prepares nothing has no such dependency."""
    jobs = engine.plan_jobs(load_recipe(ROOT / "recipes/study2022.yaml", DOMAIN), DOMAIN)
    optimize = {job.name.split("/")[1]: job for job in jobs if job.kind == "optimize"}
    prepared = {name: job.deps["prepared"] for name, job in optimize.items() if "prepared" in job.deps}
    assert prepared["structured_prune_int8"] is prepared["structured_prune_litert_int8"]
    assert prepared["structured_prune"] is not prepared["structured_prune_int8"]
    assert len({id(prepared[name]) for name in ("prune_litert", "prune_litert_int8", "pqat_litert_int8",
                                                "pcqat_litert_int8")}) == 1
    assert prepared["local_prune"] is prepared["prune_quant"]
    assert "qat_litert_int8" not in prepared and "cqat_litert_int8" not in prepared and "global_prune" not in prepared
    assert sum(job.kind == "prepare" for job in jobs) == 4
    assert prepared["structured_prune_int8"].params["options"]["finetune_epochs"] == 12


def test_a_preparation_reads_its_options_from_the_strategy_config():
    for name, entry in STRATEGIES.items():
        if entry.prepared_by:
            strategy_config = entry.config_cls()
            config = PREPARATIONS.get(entry.prepared_by).config_from(strategy_config)
            assert config.finetune_epochs == strategy_config.finetune_epochs and config.lr == strategy_config.lr


@pytest.mark.parametrize("preparation", ["channel_pruning", "l1_pruning", "magnitude_pruning"])
def test_a_prepared_network_loads_as_it_was_fine_tuned(preparation, trained, frames, test_frames, tmp_path):
    entry = PREPARATIONS.get(preparation)
    config = entry.config_cls(finetune_epochs=1, batch_size=16)
    source = StrategySource(trained / "model.pt", tmp_path / "out", (frames,))
    model, figures = prepare(entry, config, source)
    assert len(figures["finetune"]) == 1
    save_prepared(model, tmp_path / "prepared")
    loaded, same = load_prepared(entry, config, source, tmp_path / "prepared", figures)
    batch = FrameSet.load(test_frames).inputs(np.arange(8))
    with torch.no_grad():
        torch.testing.assert_close(loaded.eval()(batch), model.eval()(batch))
    assert same == figures
    if preparation != "channel_pruning":   # the masks are on again: a later QAT keeps the zeros
        masks = [name for name, _ in loaded.named_buffers() if name.endswith("mask")]
        least = 0.49 if preparation == "magnitude_pruning" else 0.29    # l1_pruning: conv 30 %, linear 50 %
        assert masks and all((layer.weight == 0).float().mean() >= least for layer in loaded.modules()
                             if isinstance(layer, (torch.nn.Conv2d, torch.nn.Linear)))


def test_a_strategy_converts_the_prepared_network_without_fine_tuning_again(trained, frames, test_frames, tmp_path):
    entry = PREPARATIONS.get("channel_pruning")
    config = entry.config_cls(finetune_epochs=1, batch_size=16)
    source = StrategySource(trained / "model.pt", tmp_path / "prepare", (frames,))
    model, figures = prepare(entry, config, source)
    save_prepared(model, tmp_path / "prepared")
    options = {"finetune_epochs": 1, "batch_size": 16, "format": "onnx"}
    converted = StrategySource(trained / "model.pt", tmp_path / "onnx", (frames,), prepared=(tmp_path / "prepared", figures))
    result = apply_strategy("structured_prune", options, converted)
    assert result["finetune"] == figures["finetune"] and result["kept_channels"] == figures["kept_channels"]
    batch = FrameSet.load(test_frames).inputs(np.arange(8))
    with torch.no_grad():
        expected = model.eval()(batch).numpy()
    np.testing.assert_allclose(load_predictor(tmp_path / "onnx", "cpu1").predict(batch.numpy()), expected,
                               rtol=1e-4, atol=1e-4)


def test_local_prune_and_prune_quant_start_from_one_l1_pruned_network(trained, frames, tmp_path):
    """The study's prune_quant is its local_prune with QAT on top: one l1_pruning prepare job, whose fine-tune
    both report (prune_quant's QAT epoch after it), and the same zeros."""
    entry = PREPARATIONS.get("l1_pruning")
    config = entry.config_cls(finetune_epochs=1, batch_size=16)
    model, figures = prepare(entry, config, StrategySource(trained / "model.pt", tmp_path / "prepare", (frames,)))
    save_prepared(model, tmp_path / "prepared")
    results = {name: apply_strategy(name, {"finetune_epochs": 1, "batch_size": 16, **extra}, StrategySource(
                   trained / "model.pt", tmp_path / name, (frames,), prepared=(tmp_path / "prepared", figures)))
               for name, extra in (("local_prune", {}), ("prune_quant", {"calibration_frames": 16}))}
    assert results["local_prune"]["finetune"] == figures["finetune"]
    assert results["prune_quant"]["finetune"][:1] == figures["finetune"] and len(results["prune_quant"]["finetune"]) == 2
    assert results["prune_quant"]["layer_sparsity"] == results["local_prune"]["layer_sparsity"]
    assert results["local_prune"]["sparsity"] > 0.29


def test_a_prepare_job_fingerprints_its_own_shaper():
    from pilotlab.specs.prepare import preparation_code
    code = {name: set(preparation_code({"preparation": name})) for name in PREPARATIONS}
    assert "pilotlab.strategies.prune" in code["l1_pruning"] and "pilotlab.strategies.channels" in code["channel_pruning"]
    assert "pilotlab.strategies.mot_torch" in code["magnitude_pruning"]
    assert "pilotlab.strategies.channels" not in code["l1_pruning"] | code["magnitude_pruning"]
