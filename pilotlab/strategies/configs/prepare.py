"""Networks prepared on the torch side for a strategy to convert (pruned, then fine-tuned), and shared.

Several strategies convert the same prepared network: structured_prune_int8 (ONNX Runtime) and
structured_prune_litert_int8 (LiteRT) both remove channels and fine-tune; prune_litert, prune_litert_int8,
pqat_litert_int8 and pcqat_litert_int8 all start from the same magnitude-pruned, fine-tuned network;
local_prune saves the L1-pruned, fine-tuned network that prune_quant goes on to fine-tune with fake
quantization. The planner makes one `prepare` job per distinct preparation (pilotlab.specs.prepare) and every
optimize job of those strategies loads the network it made, so the fine-tune runs once, not once per
strategy.

A preparation is a frozen, versioned config, like a strategy's. Its options are options of the strategies
that use it, read from their config by name (`preparation_for`): two strategies whose options agree share
the job. Its handler (`target`, "module:function", imported only where a network is prepared) gives the
network its shape (channels removed, weights masked), a step that depends only on the trained checkpoint
and the options, so loading a prepared network redoes it and then loads the fine-tuned weights.
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

from matrix.registry import Registry


@dataclass(frozen=True)
class ChannelPruning:
    """Whole channels and neurons removed (pilotlab.strategies.channels), the stem subsampled if asked
    (pilotlab.strategies.stem), then fine-tuned."""
    version: int = 2                 # 2: ranked by `criterion`, lr 3e-4 (1: by their weights' L1 norm, 1e-3)
    amount: float = 0.3
    multiple_of: int = 8
    subsample_stem: int = 0
    criterion: str = "activation"
    finetune_epochs: int = 4
    lr: float = 3e-4
    batch_size: int = 64
    distill: float = 0.0


@dataclass(frozen=True)
class MagnitudePruning:
    """The input batch-norm folded in, the smallest weights of each layer masked, fine-tuned with the mask
    held (TF-MOT's prune_low_magnitude; pilotlab.strategies.mot)."""
    version: int = 1
    sparsity: float = 0.5
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64
    distill: float = 0.0


@dataclass(frozen=True)
class L1Pruning:
    """The smallest weights of each layer zeroed by L1 norm, conv and linear layers each their own fraction
    (the 2022 study's PyTorch pruning; pilotlab.strategies.prune), fine-tuned with the mask held:
    local_prune's network, and prune_quant's before its quantization-aware fine-tune."""
    version: int = 1
    conv: float = 0.3
    linear: float = 0.5
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64


@dataclass(frozen=True, eq=False)
class PreparationEntry:
    name: str
    config_cls: type
    target: str              # "package.module:function": the network's shape, before the fine-tune

    @property
    def module(self) -> str:
        return self.target.partition(":")[0]

    def config_from(self, strategy_config) -> Any:
        """This preparation's config, its options read from a strategy's config of the same names."""
        names = [f.name for f in dataclasses.fields(self.config_cls) if f.name != "version"]
        return self.config_cls(**{name: getattr(strategy_config, name) for name in names})

    @functools.cached_property      # read for every prepare job a recipe plans (its name shows what differs)
    def defaults(self) -> dict[str, Any]:
        return self.options_of(self.config_cls())

    def options_of(self, config) -> dict[str, Any]:
        """Its options as a job's params carry them (version left out: the code's own, as a strategy's)."""
        return {f.name: getattr(config, f.name) for f in dataclasses.fields(config) if f.name != "version"}


PREPARATIONS: Registry[PreparationEntry] = Registry("preparation")
PREPARATIONS.add("channel_pruning", PreparationEntry("channel_pruning", ChannelPruning,
                                                     "pilotlab.strategies.channel_pruning:channel_pruning"))
PREPARATIONS.add("l1_pruning", PreparationEntry("l1_pruning", L1Pruning, "pilotlab.strategies.prune:l1_pruning"))
PREPARATIONS.add("magnitude_pruning", PreparationEntry("magnitude_pruning", MagnitudePruning,
                                                       "pilotlab.strategies.mot_torch:magnitude_pruning"))
