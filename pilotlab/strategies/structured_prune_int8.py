"""`structured_prune_int8`: fewer multiply-accumulates AND int8 — whole channels removed (as
`structured_prune`, rounded to multiples of 8 so the SIMD kernels run no partial blocks), fine-tuned,
then quantized statically with ONNX Runtime (as `onnxruntime_int8`, calibrated on training frames).

Why: on a CPU without VNNI (AVX2 only), ONNX Runtime's int8 PilotNet already runs near half of the
machine's int8 GEMM peak, so quantization alone cannot go much further; the remaining lever is
doing less work. Removing 30% of the channels of every layer removes about half the MACs (each conv
loses inputs and outputs), and int8 then runs those at twice the fp32 rate. It is the fastest CPU
path here at batch 1 and batch 64 (see docs/strategies.md); its MSE is reported next to the
baseline's like every other strategy's, so whether the lost channels cost driving quality shows.
Config: configs/structured_prune_int8.py.
"""
from __future__ import annotations

from pilotlab.strategies.configs.onnx_runtime import OnnxRuntimeInt8Config
from pilotlab.strategies.configs.structured_prune_int8 import StructuredPruneInt8Config
from pilotlab.strategies.onnx_runtime import quantize_int8
from pilotlab.strategies.prepared import prepared_network
from pilotlab.strategies.apply import StrategySource


def structured_prune_int8(config: StructuredPruneInt8Config, source: StrategySource) -> dict:
    model, figures = prepared_network(config, source)
    quantization = OnnxRuntimeInt8Config(calibration_frames=config.calibration_frames,
                                         calibrate_method=config.calibrate_method,
                                         float_first_conv=config.float_first_conv)
    extra = quantize_int8(model.eval(), source, quantization)
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime", dtype="int8",
                             extra={**extra, "kept_channels": figures["kept_channels"], "macs": figures["macs"]}))
    return {**figures, "calibration_frames": min(config.calibration_frames, len(source.calibration))}
