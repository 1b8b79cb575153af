"""The `channel_pruning` preparation's shape (pilotlab.strategies.configs.prepare): whole channels and
neurons removed (pilotlab.strategies.channels), the stem subsampled first if asked (pilotlab.strategies.stem);
the prepare job then fine-tunes it (pilotlab.strategies.prepared)."""
from __future__ import annotations

import torch
from torch import nn

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.channels import multiply_accumulates, remove_channels
from pilotlab.strategies.configs.prepare import ChannelPruning
from pilotlab.strategies.stem import subsample_stem

# Training frames each layer's channels are ranked on (criterion "activation"), evenly spaced through the set
# so that every recording is in it: 512 rank the study's PilotNet (65 % pruned) in ~1 s on one thread.
RANKING_FRAMES = 512


def channel_pruning(config: ChannelPruning, source: StrategySource) -> tuple[nn.Module, dict]:
    model = source.load_model()
    params_before = sum(p.numel() for p in model.parameters())
    macs_before = multiply_accumulates(model, source.input_shape)
    stem = {"stem_taps": subsample_stem(model, source.input_shape, config.subsample_stem)} if config.subsample_stem else {}
    sample = ranking_sample(source) if config.criterion == "activation" and source.prepared is None else None
    kept = remove_channels(model, config.amount, source.input_shape, config.multiple_of, sample)
    params = sum(p.numel() for p in model.parameters())
    return model, {"params": params, "nonzero_params": params, "params_before": params_before,
                   "macs": multiply_accumulates(model, source.input_shape), "macs_before": macs_before,
                   "kept_channels": kept, **stem}


def ranking_sample(source: StrategySource) -> torch.Tensor:
    """[≤ RANKING_FRAMES, C, H, W]: training frames evenly spaced through the set. Not for a prepared network
    being loaded (source.prepared): its weights come from the prepare job, and the kept counts, all its
    shape needs, follow from the amount alone (L1 ranks serve)."""
    return torch.cat(list(source.calibration_batches(RANKING_FRAMES, batch_size=RANKING_FRAMES)))
