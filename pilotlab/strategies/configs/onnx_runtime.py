"""The configs of `onnxruntime`, `onnxruntime_int8` and `dynamic_quant` (their handlers:
pilotlab/strategies/onnx_runtime.py)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pilotlab.strategies.registry import register_strategy


@dataclass(frozen=True)
class OnnxRuntimeConfig:
    version: int = 1


@dataclass(frozen=True)
class OnnxRuntimeInt8Config:
    version: int = 1
    calibration_frames: int = 512         # training frames fed to the calibrator
    calibrate_method: Literal["minmax", "entropy", "percentile"] = "minmax"
    quant_format: Literal["qdq", "qoperator"] = "qdq"
    per_channel: bool = False
    weight_type: Literal["int8", "uint8"] = "int8"
    float_first_conv: bool = True         # keep the 3-channel input conv in fp32 (faster here)


DEFAULT_OP_TYPES = ("MatMul", "Gemm")


@dataclass(frozen=True)
class DynamicQuantConfig:
    version: int = 1
    op_types: tuple[str, ...] = DEFAULT_OP_TYPES   # ONNX operator types to quantize

    def __post_init__(self):
        # a set of operator types: [Gemm, MatMul] is the default written in another order, not a new setting
        # (it ran the strategy's jobs again: outside test); the default's own order stays its order (its key)
        order = {name: i for i, name in enumerate(DEFAULT_OP_TYPES)}
        canonical = tuple(sorted(set(self.op_types), key=lambda name: (order.get(name, len(order)), name)))
        object.__setattr__(self, "op_types", canonical)


register_strategy("onnxruntime", OnnxRuntimeConfig, "pilotlab.strategies.onnx_runtime:onnxruntime_fp32",
                  takes_onnx=True)
register_strategy("onnxruntime_int8", OnnxRuntimeInt8Config, "pilotlab.strategies.onnx_runtime:onnxruntime_int8",
                  takes_onnx=True)
register_strategy("dynamic_quant", DynamicQuantConfig, "pilotlab.strategies.onnx_runtime:dynamic_quant",
                  takes_onnx=True)
