"""The `channel_pruning` preparation's shape (pilotlab.strategies.configs.prepare): whole channels and
neurons removed (pilotlab.strategies.channels), the stem subsampled first if asked (pilotlab.strategies.stem);
the prepare job then fine-tunes it (pilotlab.strategies.prepared)."""
from __future__ import annotations

from torch import nn

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.channels import multiply_accumulates, remove_channels
from pilotlab.strategies.configs.prepare import ChannelPruning
from pilotlab.strategies.stem import subsample_stem


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
