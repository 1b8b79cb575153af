"""Prepared networks (configs/prepare.py): shaped, fine-tuned, saved by the `prepare` job, loaded by the
optimize jobs of every strategy that converts them.

    model, figures = prepare(entry, config, source)                 # shape + fine-tune (the prepare job)
    save_prepared(model, folder)
    model, figures = prepared_network(strategy_config, source)      # in a strategy's handler: the prepare
                                                                    # job's (source.prepared), else made here

A shaper (`PreparationEntry.target`, in the module of the code it uses: channel_pruning.py, prune.py,
mot_torch.py) gives a fresh copy of the trained network its shape and returns it with its figures; it
depends only on the checkpoint and the options, so loading redoes it (the masks of magnitude pruning are
parametrizations, which torch cannot pickle; the pruned channels, new layers of a user's class, which it
could only pickle by reference) and then loads the state dict. This module holds none, so a strategy that
loads a prepared network fingerprints its own preparation's code, not the others'.
"""
from __future__ import annotations

import importlib
from pathlib import Path

import torch
from torch import nn

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.common import finetune
from pilotlab.strategies.configs.prepare import PreparationEntry
from pilotlab.strategies.registry import preparation_for

WEIGHTS = "network.pt"


def _shape(entry: PreparationEntry, config, source: StrategySource) -> tuple[nn.Module, dict]:
    module, _, function = entry.target.partition(":")
    return getattr(importlib.import_module(module), function)(config, source)


def prepare(entry: PreparationEntry, config, source: StrategySource) -> tuple[nn.Module, dict]:
    """The network shaped and fine-tuned, with its figures (the fine-tune's history under "finetune")."""
    model, figures = _shape(entry, config, source)
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size,
                       distill=getattr(config, "distill", 0.0))   # l1_pruning (the study's PyTorch rows) has none
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
