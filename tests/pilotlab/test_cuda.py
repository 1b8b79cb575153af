"""The CUDA rows on a host with a GPU (skipped elsewhere; the "not applicable" side is tested beside each
strategy): the cuda baseline, fp16 and bf16 run on the GPU and agree with the fp32 network on the CPU,
the timing job times them there (and the offline job takes their MSE), `cuda_graph` replays the same
network as CUDA graphs, and TensorRT builds its engines where ONNX Runtime has the provider.
First run on an H100 (2026-11-26): an ONNX artifact on the cuda profile, with an ONNX Runtime that has
no CUDA provider, failed instead of being "not applicable"; that case runs on every host below."""
from __future__ import annotations

import numpy as np
import pytest
import torch

import pilotlab.jobs.offline  # noqa: F401  (registers the kinds)
import pilotlab.jobs.timing  # noqa: F401
from matrix.kinds import KINDS, NotApplicable
from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.hardware import BUILTIN, host_fingerprint, make_profile
from pilotlab.predictor import CudaGraphs, load_predictor
from pilotlab.strategies import make_strategy_config
from pilotlab.strategies.apply import StrategySource, apply_strategy
from tests.pilotlab.jobs.test_optimize_offline import QUICK, context, dep

gpu = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")

# outputs are normalised to about [0, 1]; 16-bit floats keep ~3 (fp16) or ~2 (bf16) significant digits
TOLERANCE = {"baseline": 1e-3, "fp16": 2e-2, "bf16": 6e-2, "fp32": 1e-3}


@pytest.fixture(scope="module")
def images(test_frames) -> np.ndarray:
    return np.ascontiguousarray(FrameSet.load(test_frames).inputs(np.arange(16)).numpy())


def reference(trained, tmp_path, images) -> np.ndarray:
    apply_strategy("baseline", {}, StrategySource(trained / "model.pt", tmp_path / "cpu"))
    return load_predictor(tmp_path / "cpu", "cpu").predict(images)


@gpu
@pytest.mark.parametrize("strategy", ["baseline", "fp16", "bf16"])
def test_a_cuda_artifact_runs_on_the_gpu_and_agrees_with_fp32_on_the_cpu(strategy, trained, tmp_path, images):
    result = apply_strategy(strategy, {}, StrategySource(trained / "model.pt", tmp_path / "gpu",
                                                         hardware=BUILTIN["cuda"]))
    if strategy != "baseline":
        assert result["native"] is True
    predictor = load_predictor(tmp_path / "gpu", BUILTIN["cuda"])
    outputs = predictor.predict(images)
    assert outputs.dtype == np.float32 and outputs.shape == (len(images), 2)
    np.testing.assert_allclose(outputs, reference(trained, tmp_path, images), atol=TOLERANCE[strategy])


@gpu
def test_a_cuda_artifact_is_not_applicable_on_a_cpu_profile(trained, tmp_path):
    apply_strategy("fp16", {}, StrategySource(trained / "model.pt", tmp_path, hardware=BUILTIN["cuda"]))
    with pytest.raises(NotApplicable, match="built for CUDA"):
        load_predictor(tmp_path, "cpu")


@gpu
def test_the_timing_job_times_a_cuda_artifact_on_the_gpu(tmp_path, trained, frames, test_frames):
    out = tmp_path / "optimize"
    result = apply_strategy("fp16", {}, StrategySource(trained / "model.pt", out, hardware=BUILTIN["cuda"]))
    artifact, cuda = dep("optimize", out, {**result, "strategy": "fp16"}), make_profile("cuda").as_dict()
    timing = context(tmp_path, "timing", {"hardware": cuda, "host": host_fingerprint(), "batch": 8, "timing": QUICK},
                     {"artifact": artifact, "frames": (dep("frames", frames),)})
    timed = KINDS.get("timing").handler(timing)
    offline = context(tmp_path, "offline", {"hardware": cuda, "host": host_fingerprint()},
                      {"artifact": artifact, "test": (dep("frames", test_frames),),
                       "timing": dep("timing", timing.out, timed)})
    metrics = KINDS.get("offline").handler(offline)
    assert metrics["latency_ms"] > 0 and metrics["throughput_ips"] > 0 and metrics["mse"] >= 0
    assert host_fingerprint()["gpu"] == torch.cuda.get_device_name(0)


@gpu
@pytest.mark.parametrize("precision", ["fp32", "fp16", "int8"])
def test_tensorrt_builds_and_runs_its_engine_or_says_why_not(precision, trained, frames, tmp_path, images):
    import onnxruntime
    source = StrategySource(trained / "model.pt", tmp_path / "trt", (frames,), hardware=BUILTIN["cuda"])
    if "TensorrtExecutionProvider" not in onnxruntime.get_available_providers():
        with pytest.raises(NotApplicable, match="no TensorrtExecutionProvider"):
            apply_strategy("tensorrt", {"precision": precision, "calibration_frames": 32}, source)
        return
    apply_strategy("tensorrt", {"precision": precision, "calibration_frames": 32}, source)
    outputs = load_predictor(tmp_path / "trt", BUILTIN["cuda"]).predict(images)
    np.testing.assert_allclose(outputs, reference(trained, tmp_path, images), atol=0.2 if precision == "int8" else 2e-2)


def test_an_onnx_artifact_on_a_cuda_profile_without_the_cuda_provider_is_not_applicable(trained, tmp_path,
                                                                                        monkeypatch):
    import onnxruntime
    if "CUDAExecutionProvider" in onnxruntime.get_available_providers():
        pytest.skip("this onnxruntime has the CUDA provider")
    apply_strategy("onnxruntime", {}, StrategySource(trained / "model.pt", tmp_path))
    monkeypatch.setattr("pilotlab.predictor.apply_profile", lambda profile: None)   # as on a host with a GPU
    reason = r"needs ONNX Runtime provider.s. CUDAExecutionProvider for 'cuda'; this onnxruntime has .*\(install "
    with pytest.raises(NotApplicable, match=reason + r"onnxruntime-gpu in place of onnxruntime\)"):
        load_predictor(tmp_path, BUILTIN["cuda"])


def test_cuda_graph_precision_is_fp16_or_fp32():
    assert make_strategy_config("cuda_graph", {}).precision == "fp16"
    with pytest.raises(PilotlabError, match="precision: 'int8' is not one of fp32, fp16"):
        make_strategy_config("cuda_graph", {"precision": "int8"})


@gpu
@pytest.mark.parametrize("precision", ["fp32", "fp16"])
def test_cuda_graph_replays_the_network_at_each_batch_size(precision, trained, tmp_path, images, monkeypatch):
    result = apply_strategy("cuda_graph", {"precision": precision},
                            StrategySource(trained / "model.pt", tmp_path / "graph", hardware=BUILTIN["cuda"]))
    assert result["precision"] == precision and result["device"] == "cuda"
    predictor = load_predictor(tmp_path / "graph", BUILTIN["cuda"])
    expected = reference(trained, tmp_path, images)
    monkeypatch.setattr(CudaGraphs, "MAX_SIZES", 2)
    # a size seen again is given other frames (a replay must read the new input), 3: past the limit of 2
    for start, size in ((0, 1), (0, 16), (5, 1), (2, 3), (0, 16), (9, 1)):
        np.testing.assert_allclose(predictor.predict(images[start:start + size]), expected[start:start + size],
                                   atol=TOLERANCE[precision])
    assert sorted(shape[0] for shape in predictor._graphs._graphs) == [1, 16]
    first = predictor.predict(images[:1])
    kept = first.copy()
    np.testing.assert_allclose(predictor.predict(images[1:2]), expected[1:2], atol=TOLERANCE[precision])
    np.testing.assert_array_equal(first, kept)   # the replay wrote its output buffer again: `first` is a copy


def test_a_session_that_fell_back_from_its_first_provider_is_not_applicable():
    """ONNX Runtime quietly retries with the CUDA and CPU providers when TensorRT cannot start: the
    artifact would be timed as TensorRT while running without it."""
    from pilotlab.predictor import _check_first_provider
    from pilotlab.strategies.artifact import ArtifactMeta

    class Session:
        def __init__(self, running):
            self.running = running

        def get_providers(self):
            return self.running
    meta = ArtifactMeta(strategy="tensorrt", strategy_version=2, format="onnx", file="model.onnx",
                        runtime="onnxruntime", dtype="float16", input_shape=(1, 3, 66, 200), arch="pilotnet", config={}, labels={},
                        preprocess={}, device="cuda", extra={})
    wanted = [("TensorrtExecutionProvider", {}), ("CUDAExecutionProvider", {}), "CPUExecutionProvider"]
    _check_first_provider(Session(["TensorrtExecutionProvider", "CPUExecutionProvider"]), wanted, meta)
    with pytest.raises(NotApplicable, match="could not start TensorrtExecutionProvider here and fell back to "
                                            "CUDAExecutionProvider"):
        _check_first_provider(Session(["CUDAExecutionProvider", "CPUExecutionProvider"]), wanted, meta)
