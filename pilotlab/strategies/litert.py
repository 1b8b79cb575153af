"""LiteRT (TF Lite) strategies, the 2022 study's TensorFlow set on its own runtime:

| strategy | TF Lite converter setting (the study's row) |
| --- | --- |
| `litert` | float32, no optimization (the reference on this runtime) |
| `litert_dynamic_range` | `Optimize.DEFAULT`: int8 weights, activations quantized on the fly ("dynamic range") |
| `litert_float16` | `Optimize.DEFAULT` + `supported_types=[float16]`: fp16 weights ("float16") |
| `litert_int8` | + a representative dataset: int8 weights and activations, float input/output ("int8 with float fallback") |
| `litert_full_int8` | + `TFLITE_BUILTINS_INT8` only, int8 input and output ("integer only") |

Path: the ONNX export every ONNX strategy uses -> onnx2tf (a TensorFlow SavedModel, input kept
NCHW) -> `tf.lite.TFLiteConverter`, calibrated on training frames where the setting needs it. The
.tflite runs on the LiteRT interpreter (`ai_edge_litert`), whose CPU path is XNNPACK; the
converter needs TensorFlow, the runtime does not.

`litert_full_int8` takes int8 in and gives int8 out: the predictor quantizes the image and
dequantizes (v, w) with the scales stored in the model, as a deployment must. The 2022 study's
"Integer only Q" MSE of 28,157 is what one gets reading that int8 output as a number:
`raw_output_mse` in the result is that figure on the calibration frames, next to the real one
from the offline evaluation.

Config: configs/litert.py, which registers these strategies as needing the `edge` extra, so this
module (TensorFlow through litert_convert) is imported only where it is installed.
"""
from __future__ import annotations

from pilotlab.strategies.configs.litert import LiteRTCalibratedConfig, LiteRTConfig
from pilotlab.strategies.litert_convert import save_tflite
from pilotlab.strategies.apply import StrategySource


def _convert(mode: str, source: StrategySource, calibration_frames: int = 0) -> dict:
    return save_tflite(source.load_model(), source, mode, calibration_frames)


def litert_fp32(config: LiteRTConfig, source: StrategySource) -> dict:
    return _convert("float32", source)


def litert_dynamic_range(config: LiteRTConfig, source: StrategySource) -> dict:
    return _convert("dynamic_range", source)


def litert_float16(config: LiteRTConfig, source: StrategySource) -> dict:
    return _convert("float16", source)


def litert_int8(config: LiteRTCalibratedConfig, source: StrategySource) -> dict:
    return _convert("int8", source, config.calibration_frames)


def litert_full_int8(config: LiteRTCalibratedConfig, source: StrategySource) -> dict:
    return _convert("full_int8", source, config.calibration_frames)
