"""`structured_prune`: remove whole channels (conv) and neurons (hidden linear layers), those whose
output reaches the next layer least on the training frames (`criterion: activation`; `l1`: those of
smallest weight L1 norm), so the network really gets smaller and faster on dense kernels, then fine-tune.
The kept counts are rounded to multiples of 8 (`multiple_of`): ONNX Runtime's fp32 NCHWc and int8
kernels work on 8/16-channel blocks, so 17 channels cost as much as 24 (PilotNet pruned by 30% with
rounding runs ~25% faster in int8 than without, for 7% fewer MACs).

Works on networks whose conv/linear layers form one chain (each layer feeds the next, with
element-wise activations, dropout or a flatten between them, like PilotNet); the surgery is
checked numerically against the same network with those channels zeroed, and a network it does
not fit is "not applicable" with the reason. The output layer keeps its two neurons.
Config: configs/structured_prune.py.
"""
from __future__ import annotations

from pilotlab.strategies.common import save_float_model
from pilotlab.strategies.prepared import prepared_network
from pilotlab.strategies.configs.structured_prune import StructuredPruneConfig
from pilotlab.strategies.apply import StrategySource


def structured_prune(config: StructuredPruneConfig, source: StrategySource) -> dict:
    model, figures = prepared_network(config, source)
    save_float_model(model, source, config.format, extra={"kept_channels": figures["kept_channels"],
                                                          "macs": figures["macs"]}, same_arch=False)
    return figures
