"""Unstructured L1 pruning, as the 2022 study: `local_prune` (a fraction of each layer: conv 30%,
linear 50%) and `global_prune` (30% of all conv/linear weights ranked together), then fine-tuning
with the mask held, then the zeros baked in (torch.nn.utils.prune, which is maintained).

The network keeps its shape (zeros are stored), so the artifact is as large as the baseline and no
faster on dense kernels — exactly what the study measured; `structured_prune` is the variant that
really shrinks the network. Configs: configs/prune.py.
"""
from __future__ import annotations

from torch import nn
from torch.nn.utils import prune

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.common import finetune, save_float_model, sparsity_report, weight_layers
from pilotlab.strategies.configs.prepare import L1Pruning
from pilotlab.strategies.configs.prune import GlobalPruneConfig, LocalPruneConfig
from pilotlab.strategies.prepared import prepared_network


def local_prune(config: LocalPruneConfig, source: StrategySource) -> dict:
    """The `l1_pruning` preparation's network (pruned, fine-tuned: its prepare job's), the zeros baked in."""
    model, figures = prepared_network(config, source)
    bake_masks(model)
    save_float_model(model, source, config.format)
    return {**sparsity_report(model), "finetune": figures["finetune"]}


def l1_pruning(config: L1Pruning, source: StrategySource) -> tuple[nn.Module, dict]:
    """The `l1_pruning` preparation's shape (pilotlab.strategies.configs.prepare): the trained network
    with each layer's L1 mask on (fine-tuned then with the mask held, by the prepare job)."""
    model = source.load_model()
    prune_local(model, config.conv, config.linear)
    return model, {}


def global_prune(config: GlobalPruneConfig, source: StrategySource) -> dict:
    model = source.load_model()
    history = prune_and_finetune(model, source, config, lambda m: prune_global(m, config.amount))
    save_float_model(model, source, config.format)
    return {**sparsity_report(model), "finetune": history}


def prune_and_finetune(model: nn.Module, source: StrategySource, config, apply_masks) -> list[dict]:
    """Mask, fine-tune with the masks on (masked weights get no gradient), then make it permanent."""
    apply_masks(model)
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size)
    bake_masks(model)
    return history


def bake_masks(model: nn.Module) -> None:
    """Make the masks permanent: each weight becomes its masked value, zeros stored."""
    for _, layer in weight_layers(model):
        prune.remove(layer, "weight")


def prune_local(model: nn.Module, conv: float, linear: float) -> None:
    for _, layer in weight_layers(model):
        amount = conv if isinstance(layer, nn.Conv2d) else linear
        prune.l1_unstructured(layer, "weight", amount=amount)


def prune_global(model: nn.Module, amount: float) -> None:
    parameters = [(layer, "weight") for _, layer in weight_layers(model)]
    prune.global_unstructured(parameters, pruning_method=prune.L1Unstructured, amount=amount)
