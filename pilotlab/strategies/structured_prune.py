"""`structured_prune`: remove whole channels (conv) and neurons (hidden linear layers) with the
smallest L1 norm, so the network really gets smaller and faster on dense kernels, then fine-tune.

Works on networks whose conv/linear layers form one chain (each layer feeds the next, with
element-wise activations, dropout or a flatten between them, like PilotNet); the surgery is
checked numerically against the same network with those channels zeroed, and a network it does
not fit is "not applicable" with the reason. The output layer keeps its two neurons.
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.common import finetune, save_float_model
from pilotlab.strategies.prune import check_fraction
from pilotlab.strategies.registry import StrategySource, register_strategy


@dataclass(frozen=True)
class StructuredPruneConfig:
    version: int = 1
    amount: float = 0.3              # fraction of each layer's channels / neurons removed
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    format: str = "torchscript"      # torchscript | onnx (the shapes change: no checkpoint)


@register_strategy("structured_prune", StructuredPruneConfig)
def structured_prune(config: StructuredPruneConfig, source: StrategySource) -> dict:
    check_fraction("structured_prune", "amount", config.amount)
    from pilotlab.strategies.channels import remove_channels  # torch
    model = source.load_model()
    params_before = sum(p.numel() for p in model.parameters())
    kept = remove_channels(model, config.amount, source.input_shape)
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size)
    save_float_model(model, source, "structured_prune", config.format, extra={"kept_channels": kept},
                     same_arch=False)
    params = sum(p.numel() for p in model.parameters())
    return {"params": params, "nonzero_params": params, "params_before": params_before,
            "kept_channels": kept, "finetune": history}
