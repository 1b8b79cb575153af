"""ONNX Runtime strategies: `onnxruntime` (fp32), `onnxruntime_int8` (static, calibrated) and
`dynamic_quant` (the study's dynamic-range int8).

Why ONNX Runtime: it is maintained, deployable without Python or PyTorch, and on this CPU it is the
fastest batch-1 path we have (its MLAS int8 kernels beat PyTorch's; see the benchmark). It is also
the CPU counterpart of the study's TensorRT runs: a separate optimising inference engine fed an
exported graph.

- `onnxruntime_int8` quantizes weights and activations statically with ONNX Runtime's own
  calibrator on training frames. QDQ format, per-tensor weights, u8 activations and s8 weights
  measured fastest at batch 1 here (per-channel and the QOperator format were slower; u8u8 too).
  The first convolution (3 input channels) stays fp32 by default: ONNX Runtime's fp32 NCHWc
  kernel runs it about twice as fast as its int8 one, and the whole network ~20% faster at
  batch 1 (interleaved A/B, one thread).
- `dynamic_quant` quantizes only MatMul/Gemm (the fully connected layers, 85% of PilotNet's
  weights), as the study's `quantize_dynamic` did for nn.Linear: ONNX Runtime's dynamic int8 on
  convolutions is slower than fp32 here. torch.ao.quantization.quantize_dynamic still runs in
  torch 2.13 but is deprecated.

Configs: configs/onnx_runtime.py.
"""
from __future__ import annotations

import contextlib
import io
import logging
import tempfile
from pathlib import Path

import onnx
from onnxruntime.quantization import CalibrationMethod, QuantFormat, QuantType, quantize_dynamic, quantize_static
from onnxruntime.quantization.shape_inference import quant_pre_process

from pilotlab.errors import PilotlabError
from pilotlab.strategies.artifact import INPUT_NAME
from pilotlab.strategies.configs.onnx_runtime import DynamicQuantConfig, OnnxRuntimeConfig, OnnxRuntimeInt8Config
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import export_onnx


def onnxruntime_fp32(config: OnnxRuntimeConfig, source: StrategySource) -> dict:
    export_onnx(source.load_model(), source.out / "model.onnx", source.input_shape)
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime",
                             dtype="float32"))
    return {}


def onnxruntime_int8(config: OnnxRuntimeInt8Config, source: StrategySource) -> dict:
    extra = quantize_int8(source.load_model(), source, config)
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime",
                             dtype="int8", extra=extra))
    return {"calibration_frames": min(config.calibration_frames, len(source.calibration))}


def quantize_int8(model, source: StrategySource, config: OnnxRuntimeInt8Config) -> dict:
    """Export `model` and quantize it statically into source.out/model.onnx with ONNX Runtime's
    calibrator on training frames; returns what artifact.json's `extra` records about it."""
    methods = {"minmax": CalibrationMethod.MinMax, "entropy": CalibrationMethod.Entropy,
               "percentile": CalibrationMethod.Percentile}
    formats = {"qdq": QuantFormat.QDQ, "qoperator": QuantFormat.QOperator}
    types = {"int8": QuantType.QInt8, "uint8": QuantType.QUInt8}
    for option, value, known in (("calibrate_method", config.calibrate_method, methods),
                                 ("quant_format", config.quant_format, formats),
                                 ("weight_type", config.weight_type, types)):
        if value not in known:
            raise PilotlabError(f"{option}: {value!r} is not one of {', '.join(known)}")
    with tempfile.TemporaryDirectory() as tmp, quiet_quantizer():
        prepared = prepared_fp32(model, source, Path(tmp))
        excluded = first_conv(prepared) if config.float_first_conv else []
        quantize_static(str(prepared), str(source.out / "model.onnx"), CalibrationReader(source, config.calibration_frames),
                        quant_format=formats[config.quant_format], per_channel=config.per_channel,
                        activation_type=QuantType.QUInt8, weight_type=types[config.weight_type],
                        calibrate_method=methods[config.calibrate_method], nodes_to_exclude=excluded)
    return {"quantizer": "onnxruntime.quantize_static", "activations": "uint8",
            "weights": config.weight_type, "fp32_nodes": excluded}


def dynamic_quant(config: DynamicQuantConfig, source: StrategySource) -> dict:
    with tempfile.TemporaryDirectory() as tmp, quiet_quantizer():
        prepared = prepared_fp32(source.load_model(), source, Path(tmp))
        quantize_dynamic(str(prepared), str(source.out / "model.onnx"), weight_type=QuantType.QInt8,
                         op_types_to_quantize=list(config.op_types))
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime",
                             dtype="int8", extra={"quantizer": "onnxruntime.quantize_dynamic",
                                                  "op_types": list(config.op_types)}))
    return {}


def prepared_fp32(model, source: StrategySource, tmp: Path) -> Path:
    """The fp32 model exported and pre-processed for quantization (shape inference, fusions)."""
    export_onnx(model, tmp / "fp32.onnx", source.input_shape)
    quant_pre_process(str(tmp / "fp32.onnx"), str(tmp / "prepared.onnx"))
    return tmp / "prepared.onnx"


def first_conv(model_path: Path) -> list[str]:
    graph = onnx.load(str(model_path)).graph
    return [node.name for node in graph.node if node.op_type == "Conv"][:1]


class CalibrationReader:
    """ONNX Runtime's CalibrationDataReader protocol over the training frames."""

    def __init__(self, source: StrategySource, max_frames: int):
        self._batches = (({INPUT_NAME: b.numpy()}) for b in source.calibration_batches(max_frames))

    def get_next(self):
        return next(self._batches, None)

    def __iter__(self):
        return self._batches


@contextlib.contextmanager
def quiet_quantizer():
    """ORT's quantizer logs a line per node and warns about pre-processing; keep the job log readable."""
    logger = logging.getLogger()
    level = logger.level
    logger.setLevel(logging.WARNING)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        logger.setLevel(level)
