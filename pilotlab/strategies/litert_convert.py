"""PyTorch -> .tflite for the LiteRT strategies (litert.py): the ONNX export, onnx2tf to a
TensorFlow SavedModel (input kept NCHW, so every artifact takes the same tensor), then TF Lite's
converter with the study's settings. TensorFlow and onnx2tf are imported here only: the edge
extra installs them, and the strategies using this module are registered as requiring it, so it is
imported only where they are installed."""
from __future__ import annotations

import contextlib
import io
import logging
import os
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from pilotlab.strategies.artifact import INPUT_NAME
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import export_onnx   # torch before TensorFlow, the order the jobs always had

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")   # before TensorFlow loads: its C++ logs are pages long
import onnx2tf  # noqa: E402
import tensorflow as tf  # noqa: E402
import tf_keras  # noqa: E402   (onnx2tf's Keras)
from ai_edge_litert.interpreter import Interpreter  # noqa: E402

MODES = {  # mode -> (artifact dtype, what artifact.json says about it)
    "float32": ("float32", "no optimization"),
    "dynamic_range": ("int8", "Optimize.DEFAULT: int8 weights, activations quantized at run time"),
    "float16": ("float16", "Optimize.DEFAULT, supported_types=[float16]: fp16 weights"),
    "int8": ("int8", "Optimize.DEFAULT + representative dataset: int8, float input/output"),
    "full_int8": ("int8", "TFLITE_BUILTINS_INT8 only, int8 input and output"),
}


def save_tflite(model, source: StrategySource, mode: str, calibration_frames: int) -> dict:
    """Write source.out/model.tflite and artifact.json; returns the strategy's result figures."""
    with tempfile.TemporaryDirectory() as tmp, _quiet():
        saved = _saved_model(model, source, Path(tmp))
        (source.out / "model.tflite").write_bytes(_convert(saved, mode, source, calibration_frames))
    dtype, setting = MODES[mode]
    extra = {"converter": f"onnx2tf + tf.lite.TFLiteConverter: {setting}", "backend": "XNNPACK (LiteRT CPU)"}
    result = {"calibration_frames": min(calibration_frames, len(source.calibration))} if calibration_frames else {}
    if mode == "full_int8":
        extra |= _io_quantization(source.out / "model.tflite")
        result["raw_output_mse"] = raw_output_mse(source.out / "model.tflite", source, calibration_frames)
    source.write(source.meta(format="tflite", file="model.tflite", runtime="litert", dtype=dtype,
                             extra=extra))
    return result


def _saved_model(model, source: StrategySource, tmp: Path) -> Path:
    """The SavedModel onnx2tf writes with output_signaturedefs=True (one `serving_default` endpoint),
    written here from the Keras model it returns: onnx2tf's own save also converts the model to two
    .tflite files (~1.5 s) that the strategies do not use."""
    export_onnx(model, tmp / "model.onnx", source.input_shape)
    keras_model = onnx2tf.convert(input_onnx_file_path=str(tmp / "model.onnx"), output_folder_path=str(tmp / "saved"),
                                  keep_ncw_or_nchw_or_ncdhw_input_names=[INPUT_NAME], output_signaturedefs=True,
                                  non_verbose=True, disable_model_save=True)
    archive = tf_keras.export.ExportArchive()
    archive.add_endpoint(name="serving_default", fn=lambda *inputs: keras_model(inputs),
                         input_signature=[tf.TensorSpec(t.shape, t.dtype, t.name) for t in keras_model.inputs])
    archive.write_out(str(tmp / "saved"))
    return tmp / "saved"


def _convert(saved: Path, mode: str, source: StrategySource, calibration_frames: int) -> bytes:
    converter = tf.lite.TFLiteConverter.from_saved_model(str(saved))
    if mode != "float32":
        converter.optimizations = [tf.lite.Optimize.DEFAULT]
    if mode == "float16":
        converter.target_spec.supported_types = [tf.float16]
    if mode in ("int8", "full_int8"):
        converter.representative_dataset = lambda: _representative(source, calibration_frames)
    if mode == "full_int8":
        converter.target_spec.supported_ops = [tf.lite.OpsSet.TFLITE_BUILTINS_INT8]
        converter.inference_input_type = converter.inference_output_type = tf.int8
    return converter.convert()


def _representative(source: StrategySource, max_frames: int) -> Iterator[list[np.ndarray]]:
    for batch in source.calibration_batches(max_frames):
        for image in batch.numpy():
            yield [image[None]]


def _io_quantization(path: Path) -> dict:
    interpreter = Interpreter(model_path=str(path))
    (scale_in, zero_in), (scale_out, zero_out) = (interpreter.get_input_details()[0]["quantization"],
                                                  interpreter.get_output_details()[0]["quantization"])
    return {"input_quantization": {"scale": scale_in, "zero_point": zero_in},
            "output_quantization": {"scale": scale_out, "zero_point": zero_out}}


def raw_output_mse(path: Path, source: StrategySource, max_frames: int) -> float:
    """MSE against the normalised labels of the int8 output read as it comes, without its scale and
    zero point: the mistake that gave the 2022 study's "Integer only" row an MSE of 28,157."""
    data = source.calibration
    index = np.unique(np.linspace(0, len(data) - 1, min(max_frames, len(data))).astype(np.int64))
    interpreter = Interpreter(model_path=str(path), num_threads=1)
    scale, zero = interpreter.get_input_details()[0]["quantization"]
    images = np.clip(np.round(data.inputs(index, source.frames).numpy() / scale) + zero, -128, 127).astype(np.int8)
    interpreter.resize_tensor_input(interpreter.get_input_details()[0]["index"], list(images.shape))
    interpreter.allocate_tensors()
    interpreter.set_tensor(interpreter.get_input_details()[0]["index"], images)
    interpreter.invoke()
    raw = interpreter.get_tensor(interpreter.get_output_details()[0]["index"]).astype(np.float32)
    return float(((raw - source.labels.normalise(np.asarray(data.labels[index]))) ** 2).mean())


@contextlib.contextmanager
def _quiet():
    """TensorFlow and onnx2tf print pages of progress; keep the job log readable."""
    root = logging.getLogger()
    level = root.level
    root.setLevel(logging.ERROR)
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()), \
                warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        root.setLevel(level)
