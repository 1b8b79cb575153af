"""`prune_quant`: the study's best PyTorch model — L1 pruning (per layer, fine-tuned) followed by
quantization-aware fine-tuning that keeps the pruned weights at zero, then int8 (see pt2e.py for
why torchao PT2E -> ONNX QDQ -> ONNX Runtime). Symmetric int8 weights map 0.0 to 0 exactly, so the
sparsity survives quantization. Config: configs/prune_quant.py.
"""
from __future__ import annotations

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.common import sparsity_report
from pilotlab.strategies.configs.prune_quant import PruneQuantConfig
from pilotlab.strategies.prepared import prepared_network
from pilotlab.strategies.prune import bake_masks
from pilotlab.strategies.pt2e import quantization_aware_finetune


def prune_quant(config: PruneQuantConfig, source: StrategySource) -> dict:
    """local_prune's network (the shared `l1_pruning` prepare job's, when the options agree), then QAT."""
    model, figures = prepared_network(config, source)
    bake_masks(model)
    pruned = sparsity_report(model)
    qat_history = quantization_aware_finetune(model, source, config.quantization_aware, keep_zeros=True)
    return {**pruned, "finetune": figures["finetune"] + qat_history}
