"""`tensorrt`: the study's TensorRT runs, through ONNX Runtime's TensorRT execution provider
(fp16 engines built from the exported ONNX model when the session first runs, cached beside it).

Only on a CUDA hardware target with onnxruntime-gpu built with TensorRT; elsewhere "not
applicable" with the reason. (torch-tensorrt would also do; it is not installed here.)
Config: configs/cuda.py.
"""
from __future__ import annotations

import onnxruntime

from matrix.kinds import NotApplicable
from pilotlab.strategies.common import require_cuda_target
from pilotlab.strategies.configs.cuda import TensorRTConfig
from pilotlab.strategies.registry import StrategySource
from pilotlab.strategies.saving import export_onnx


def tensorrt(config: TensorRTConfig, source: StrategySource) -> dict:
    require_cuda_target(source)
    if "TensorrtExecutionProvider" not in onnxruntime.get_available_providers():
        raise NotApplicable("tensorrt: this onnxruntime has no TensorrtExecutionProvider "
                            f"(providers: {', '.join(onnxruntime.get_available_providers())}); "
                            "install onnxruntime-gpu with TensorRT")
    export_onnx(source.load_model(), source.out / "model.onnx", source.input_shape)
    precision = "float16" if config.fp16 else "float32"
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime",
                             dtype=precision, device="cuda",
                             extra={"providers": ["TensorrtExecutionProvider", "CUDAExecutionProvider"],
                                    "trt_fp16": config.fp16}))
    return {}
