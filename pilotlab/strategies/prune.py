"""Unstructured L1 pruning, as the 2022 study: `local_prune` (a fraction of each layer: conv 30%,
linear 50%) and `global_prune` (30% of all conv/linear weights ranked together), then fine-tuning
with the mask held, then the zeros baked in (torch.nn.utils.prune, which is maintained).

The network keeps its shape (zeros are stored), so the artifact is as large as the baseline and no
faster on dense kernels — exactly what the study measured; `structured_prune` is the variant that
really shrinks the network.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from pilotlab.errors import PilotlabError
from pilotlab.strategies.common import finetune, save_float_model, sparsity_report, weight_layers
from pilotlab.strategies.registry import StrategySource, register_strategy

if TYPE_CHECKING:  # torch is imported inside the functions: planning imports this module
    from torch import nn


@dataclass(frozen=True)
class LocalPruneConfig:
    version: int = 1
    conv: float = 0.3                # fraction of each conv layer's weights set to zero
    linear: float = 0.5              # fraction of each linear layer's weights set to zero
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    format: str = "checkpoint"       # checkpoint (eager, as the study) | torchscript | onnx

    def __post_init__(self) -> None:  # checked when the recipe is read, not when the job runs
        check_fraction("conv", self.conv)
        check_fraction("linear", self.linear)


@dataclass(frozen=True)
class GlobalPruneConfig:
    version: int = 1
    amount: float = 0.3              # fraction of all conv/linear weights set to zero
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    format: str = "checkpoint"

    def __post_init__(self) -> None:
        check_fraction("amount", self.amount)


@register_strategy("local_prune", LocalPruneConfig)
def local_prune(config: LocalPruneConfig, source: StrategySource) -> dict:
    model = source.load_model()
    history = prune_and_finetune(model, source, config,
                                 lambda m: prune_local(m, config.conv, config.linear))
    save_float_model(model, source, config.format)
    return {**sparsity_report(model), "finetune": history}


@register_strategy("global_prune", GlobalPruneConfig)
def global_prune(config: GlobalPruneConfig, source: StrategySource) -> dict:
    model = source.load_model()
    history = prune_and_finetune(model, source, config, lambda m: prune_global(m, config.amount))
    save_float_model(model, source, config.format)
    return {**sparsity_report(model), "finetune": history}


def prune_and_finetune(model: nn.Module, source: StrategySource, config, apply_masks) -> list[dict]:
    """Mask, fine-tune with the masks on (masked weights get no gradient), then make it permanent."""
    from torch.nn.utils import prune
    apply_masks(model)
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size)
    for _, layer in weight_layers(model):
        prune.remove(layer, "weight")
    return history


def prune_local(model: nn.Module, conv: float, linear: float) -> None:
    from torch import nn
    from torch.nn.utils import prune
    for _, layer in weight_layers(model):
        amount = conv if isinstance(layer, nn.Conv2d) else linear
        prune.l1_unstructured(layer, "weight", amount=amount)


def prune_global(model: nn.Module, amount: float) -> None:
    from torch.nn.utils import prune
    parameters = [(layer, "weight") for _, layer in weight_layers(model)]
    prune.global_unstructured(parameters, pruning_method=prune.L1Unstructured, amount=amount)


def check_fraction(option: str, value: float) -> None:
    if not 0.0 <= value < 1.0:
        raise PilotlabError(f"{option}: {value} is not a fraction in [0, 1)")
