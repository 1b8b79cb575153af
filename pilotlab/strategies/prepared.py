"""Prepared networks (configs/prepare.py): shaped, fine-tuned, saved by the `prepare` job, loaded by the
optimize jobs of every strategy that converts them.

    model, figures = prepare(entry, config, source)                 # shape + fine-tune (the prepare job)
    save_prepared(model, folder)
    model, figures = prepared_network(strategy_config, source)      # in a strategy's handler: the prepare
                                                                    # job's (source.prepared), else made here

A shaper (`PreparationEntry.target`) gives a fresh copy of the trained network its shape and returns it
with its figures; it depends only on the checkpoint and the options, so loading redoes it (the masks of
magnitude pruning are parametrizations, which torch cannot pickle; the pruned channels, new layers of a
user's class, which it could only pickle by reference) and then loads the state dict.
"""
from __future__ import annotations

import importlib
from pathlib import Path

import torch
from torch import nn

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.channels import multiply_accumulates, remove_channels
from pilotlab.strategies.common import finetune
from pilotlab.strategies.configs.prepare import ChannelPruning, MagnitudePruning, PreparationEntry
from pilotlab.strategies.mot_torch import add_masks, fold, magnitude_masks
from pilotlab.strategies.registry import preparation_for
from pilotlab.strategies.stem import subsample_stem

WEIGHTS = "network.pt"


def channel_pruning(config: ChannelPruning, source: StrategySource) -> tuple[nn.Module, dict]:
    model = source.load_model()
    params_before = sum(p.numel() for p in model.parameters())
    macs_before = multiply_accumulates(model, source.input_shape)
    stem = {"stem_taps": subsample_stem(model, source.input_shape, config.subsample_stem)} if config.subsample_stem else {}
    kept = remove_channels(model, config.amount, source.input_shape, config.multiple_of)
    params = sum(p.numel() for p in model.parameters())
    return model, {"params": params, "nonzero_params": params, "params_before": params_before,
                   "macs": multiply_accumulates(model, source.input_shape), "macs_before": macs_before,
                   "kept_channels": kept, **stem}


def magnitude_pruning(config: MagnitudePruning, source: StrategySource) -> tuple[nn.Module, dict]:
    """The masks stay on (parametrizations), so that a later step (QAT) keeps the zeros too."""
    model = fold(source.load_model())
    add_masks(model, magnitude_masks(model, config.sparsity))
    return model, {}


def _shape(entry: PreparationEntry, config, source: StrategySource) -> tuple[nn.Module, dict]:
    module, _, function = entry.target.partition(":")
    return getattr(importlib.import_module(module), function)(config, source)


def prepare(entry: PreparationEntry, config, source: StrategySource) -> tuple[nn.Module, dict]:
    """The network shaped and fine-tuned, with its figures (the fine-tune's history under "finetune")."""
    model, figures = _shape(entry, config, source)
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size,
                       distill=config.distill)
    return model, {**figures, "finetune": history}


def save_prepared(model: nn.Module, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    torch.save(model.state_dict(), folder / WEIGHTS)


def load_prepared(entry: PreparationEntry, config, source: StrategySource, folder: Path,
                  figures: dict) -> tuple[nn.Module, dict]:
    model, _ = _shape(entry, config, source)
    model.load_state_dict(torch.load(folder / WEIGHTS, weights_only=True))
    return model, dict(figures)


def prepared_network(strategy_config, source: StrategySource) -> tuple[nn.Module, dict]:
    """The prepared network the strategy being applied converts, and its figures: the one the prepare job
    made (`source.prepared`), else prepared here (a strategy applied outside a run: `apply_strategy`)."""
    entry, config = preparation_for(source.strategy, strategy_config)
    if source.prepared is None:
        return prepare(entry, config, source)
    folder, figures = source.prepared
    return load_prepared(entry, config, source, folder, figures)
