"""TensorRT at the study's three precisions: what can be checked without a GPU (the options, the int8
graph TensorRT is given, "not applicable" on a CPU target), the engines themselves on a CUDA host."""
import numpy as np
import onnx
import onnxruntime
import pytest
import torch

from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.strategies import make_strategy_config
from pilotlab.strategies.apply import StrategySource


def test_the_precision_is_one_of_the_studys_three():
    assert make_strategy_config("tensorrt", {}).precision == "fp16"
    assert make_strategy_config("tensorrt", {"precision": "int8"}).precision == "int8"
    with pytest.raises(PilotlabError, match="precision: 'int4' is not one of fp32, fp16, int8"):
        make_strategy_config("tensorrt", {"precision": "int4"})


def test_int8_gives_tensorrt_a_symmetric_qdq_graph_calibrated_on_training_frames(trained, frames, test_frames,
                                                                                 tmp_path):
    from pilotlab.strategies.cuda import quantize_for_tensorrt
    source = StrategySource(trained / "model.pt", tmp_path, (frames,))
    model = source.load_model()
    extra = quantize_for_tensorrt(model, source, calibration_frames=32)
    graph = onnx.load(tmp_path / "model.onnx").graph
    quantizers = [n for n in graph.node if n.op_type == "QuantizeLinear"]
    assert len(quantizers) >= 5 and extra["calibration_frames"] == 32
    constants = {init.name: onnx.numpy_helper.to_array(init) for init in graph.initializer}
    zero_points = [constants[n.input[2]] for n in quantizers]
    assert all(z.dtype == np.int8 and not z.any() for z in zero_points)       # symmetric: TensorRT's int8
    session = onnxruntime.InferenceSession(str(tmp_path / "model.onnx"), providers=["CPUExecutionProvider"])
    images = np.ascontiguousarray(FrameSet.load(test_frames).inputs(np.arange(6)).numpy())
    quantized = session.run(None, {session.get_inputs()[0].name: images})[0]
    with torch.no_grad():
        exact = model(torch.from_numpy(images)).numpy()
    # symmetric int8 activations spend a bit on the sign a ReLU never uses: on this random network outputs
    # (normalised to [0, 1]) stray by up to 0.15 (0.01 asymmetric); on the study's trained PilotNet by 0.024
    np.testing.assert_allclose(quantized, exact, atol=0.2)


def test_a_cuda_strategy_on_a_cpu_profile_is_not_applicable_without_naming_another_profile():
    """Outside test: on cpu1 it said "'cpu' is a CPU profile" (one optimize job serves every CPU profile)."""
    from types import SimpleNamespace
    from matrix.kinds import NotApplicable
    from pilotlab.hardware import BUILTIN
    from pilotlab.strategies.common import require_cuda_target
    with pytest.raises(NotApplicable) as caught:
        require_cuda_target(SimpleNamespace(strategy="tensorrt", hardware=BUILTIN["cpu"]))
    assert str(caught.value) == "tensorrt runs on a CUDA hardware target, not on a CPU profile"
