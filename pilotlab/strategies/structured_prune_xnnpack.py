"""Structured pruning then XNNPACK int8: `structured_prune_litert_int8` — the `structured_prune_int8`
recipe (30 % of the channels removed, kept counts rounded to multiples of 8, fine-tuned) with the
int8 step done by LiteRT (TF Lite's int8 with float input/output), the runtime that runs PilotNet's
int8 fastest here at batch 1 and batch 64 (ExecuTorch's XNNPACK was measured too: slower,
docs/strategies.md).

Why: ONNX Runtime's int8 PilotNet spends a third of its batch-1 time outside the int8 GEMMs
(layout transposes around the fp32 first convolution, quantize/dequantize nodes, the fully
connected layers); XNNPACK keeps NHWC int8 activations from the first layer to the last and
runs the whole network in about a third of ORT's time (docs/strategies.md). Half the MACs on top
of that is what reaches ≥ 10× fp32 eager at batch 1.

Config: configs/structured_prune_xnnpack.py, which registers the strategy as needing the `edge`
extra, so this module (TensorFlow through litert_convert) is imported only where it is installed.
"""
from __future__ import annotations

import dataclasses

from pilotlab.strategies.artifact import read_meta
from pilotlab.strategies.configs.structured_prune_xnnpack import StructuredPruneXnnpackConfig
from pilotlab.strategies.litert_convert import save_tflite
from pilotlab.strategies.prepared import prepared_network
from pilotlab.strategies.apply import StrategySource


def _record_pruning(source: StrategySource, figures: dict) -> None:
    """Add the pruning figures to the artifact.json the int8 step wrote (the benchmark reads macs)."""
    meta = read_meta(source.out)
    source.write(dataclasses.replace(meta, extra={**meta.extra, "kept_channels": figures["kept_channels"],
                                                  "macs": figures["macs"]}))


def structured_prune_litert_int8(config: StructuredPruneXnnpackConfig, source: StrategySource) -> dict:
    model, figures = prepared_network(config, source)
    result = save_tflite(model.eval(), source, "int8", config.calibration_frames)
    _record_pruning(source, figures)
    return {**result, **figures}
