"""`tensorrt`: the study's TF-TRT runs, through ONNX Runtime's TensorRT execution provider, at fp32,
fp16 or int8 (engines built from the exported ONNX model when the session first runs).

int8 is TensorRT's explicit quantization: the model is quantized here with ONNX Runtime's calibrator
on training frames into a QDQ graph with symmetric int8 activations and per-channel weights (what
TensorRT takes; the scales travel in the model, no calibration table), and the engine runs its
quantized layers in int8, the rest in fp16. The first convolution stays float, as in
`onnxruntime_int8`: it sees the raw image (3 channels, little work) and costs the most accuracy in int8.

Only on a CUDA hardware target with onnxruntime-gpu built with TensorRT; elsewhere "not
applicable" with the reason. Config: configs/cuda.py.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import onnxruntime
from onnxruntime.quantization import CalibrationMethod, QuantFormat, QuantType, quantize_static

from matrix.kinds import NotApplicable
from pilotlab.strategies.common import require_cuda_target
from pilotlab.strategies.configs.cuda import TensorRTConfig
from pilotlab.strategies.onnx_runtime import CalibrationReader, first_conv, prepared_fp32, quiet_quantizer
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import export_onnx

DTYPES = {"fp32": "float32", "fp16": "float16", "int8": "int8"}


def tensorrt(config: TensorRTConfig, source: StrategySource) -> dict:
    require_cuda_target(source)
    if "TensorrtExecutionProvider" not in onnxruntime.get_available_providers():
        raise NotApplicable("tensorrt: this onnxruntime has no TensorrtExecutionProvider "
                            f"(providers: {', '.join(onnxruntime.get_available_providers())}); "
                            "install onnxruntime-gpu with TensorRT")
    model, extra = source.load_model(), {}
    if config.precision == "int8":
        extra = quantize_for_tensorrt(model, source, config.calibration_frames)
    else:
        export_onnx(model, source.out / "model.onnx", source.input_shape)
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime",
                             dtype=DTYPES[config.precision], device="cuda",
                             extra={**extra, "providers": ["TensorrtExecutionProvider", "CUDAExecutionProvider"],
                                    "trt_fp16": config.precision != "fp32", "trt_int8": config.precision == "int8"}))
    return {"precision": config.precision}


def quantize_for_tensorrt(model, source: StrategySource, calibration_frames: int) -> dict:
    """`model` as a QDQ graph in source.out/model.onnx, symmetric int8 activations and per-channel
    int8 weights (zero points 0: TensorRT's int8), calibrated on training frames. Runs on any CPU."""
    with tempfile.TemporaryDirectory() as tmp, quiet_quantizer():
        prepared = prepared_fp32(model, source, Path(tmp))
        quantize_static(str(prepared), str(source.out / "model.onnx"), CalibrationReader(source, calibration_frames),
                        quant_format=QuantFormat.QDQ, per_channel=True, activation_type=QuantType.QInt8,
                        weight_type=QuantType.QInt8, calibrate_method=CalibrationMethod.MinMax,
                        extra_options={"ActivationSymmetric": True, "WeightSymmetric": True},
                        nodes_to_exclude=(excluded := first_conv(prepared)))
    return {"quantizer": "onnxruntime.quantize_static (QDQ, symmetric)", "activations": "int8", "weights": "int8",
            "fp16_nodes": excluded, "calibration_frames": min(calibration_frames, len(source.calibration))}
