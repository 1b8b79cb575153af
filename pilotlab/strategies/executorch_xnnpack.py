"""ExecuTorch with its XNNPACK backend: `executorch` (fp32) and `executorch_int8` (static int8 by
the XNNPACK quantizer, calibrated on training frames) — PyTorch's own on-device runtime, and the
same XNNPACK kernels TF Lite / LiteRT runs on the CPU.

Why: on this AVX2 CPU XNNPACK's int8 convolutions run PilotNet at batch 1 in a third of ONNX
Runtime's int8 time (its QS8 kernels keep NHWC int8 activations end to end, where ORT's QDQ graph
converts layouts around the first fp32 convolution and the fully connected layers); see
docs/strategies.md. The flow is the maintained one: torch.export -> torchao PT2E `prepare_pt2e`
with ExecuTorch's XNNPACKQuantizer (symmetric int8, weights per output channel) -> calibration ->
`convert_pt2e` -> `to_edge_transform_and_lower` with the XNNPACK partitioner -> a .pte file that
the ExecuTorch runtime loads without PyTorch's eager stack.

The batch dimension is dynamic up to `max_batch`, and the memory plan may hold fewer (15 for
PilotNet with ExecuTorch 1.5): artifact.json records the planned batch and the predictor runs
larger batches in slices of it.
"""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.strategies.edge import EXECUTORCH, require
from pilotlab.strategies.registry import StrategySource, register_strategy

PTE = "model.pte"


@dataclass(frozen=True)
class ExecuTorchConfig:
    version: int = 1
    max_batch: int = 64              # the export's upper bound on the batch (larger ones are sliced)


@register_strategy("executorch", ExecuTorchConfig)
def executorch_fp32(config: ExecuTorchConfig, source: StrategySource) -> dict:
    require(source, EXECUTORCH)
    from pilotlab.strategies.executorch_lower import save_pte
    save_pte(source.load_model(), source, config.max_batch, quantizer=None)
    return {}


@dataclass(frozen=True)
class ExecuTorchInt8Config:
    version: int = 1
    calibration_frames: int = 512    # training frames observed before convert_pt2e
    per_channel: bool = True         # weight scales per output channel (XNNPACK's QC8 kernels)
    max_batch: int = 64


@register_strategy("executorch_int8", ExecuTorchInt8Config)
def executorch_int8(config: ExecuTorchInt8Config, source: StrategySource) -> dict:
    require(source, EXECUTORCH)
    from pilotlab.strategies.executorch_lower import save_pte
    save_pte(source.load_model(), source, config.max_batch,
             quantizer={"per_channel": config.per_channel, "calibration_frames": config.calibration_frames})
    return {"calibration_frames": min(config.calibration_frames, len(source.calibration))}
