"""One way to run any strategy's artifact: offline evaluation, benchmarks and the simulator's brain.

    predictor = load_predictor(artifact_dir, "cpu1")          # or a HardwareProfile / profile dict
    vw = predictor.predict(batch)   # float32 [N, C, 66, 200], RGB in [0, 1] -> float32 [N, 2]
    predictor.meta.labels           # {"v": [lo, hi], "w": [lo, hi]} to denormalise vw
    predictor.meta.preprocess       # how camera images were cropped/resized for this network

`predict` does no work it can avoid per call (a brain calls it at batch 1 every control step): the
numpy input is handed to the runtime without a copy (torch.from_numpy / ONNX Runtime's binding),
the output comes back as the runtime's own array, and casts happen only for half-precision
artifacts. The input must be C-contiguous float32.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from matrix.kinds import NotApplicable
from pilotlab.errors import PilotlabError, library_message
from pilotlab.hardware import BUILTIN, HardwareProfile, apply_profile, make_profile, profile_from_dict
from pilotlab.strategies.artifact import INPUT_NAME, OUTPUT_NAME, ArtifactMeta, read_meta


class Predictor:
    """Runs one artifact on one hardware profile. Subclasses implement `_run`."""

    def __init__(self, meta: ArtifactMeta, hardware: HardwareProfile):
        self.meta = meta
        self.hardware = hardware
        self._trailing = tuple(meta.input_shape[1:])

    @property
    def threads(self) -> int:
        return self.hardware.cpu_threads

    def predict(self, batch: np.ndarray) -> np.ndarray:
        if batch.dtype != np.float32 or batch.shape[1:] != self._trailing:
            raise PilotlabError(f"predict: expected float32 [N, {', '.join(map(str, self._trailing))}], "
                                f"got {batch.dtype} {list(batch.shape)}")
        return self._run(batch)

    def _run(self, batch: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class TorchPredictor(Predictor):
    """A pilotlab checkpoint (eager) or a TorchScript file."""

    def __init__(self, meta: ArtifactMeta, hardware: HardwareProfile, module):
        import torch
        super().__init__(meta, hardware)
        self._torch = torch
        self._module = module
        self._device = torch.device(hardware.device)
        self._dtype = getattr(torch, meta.dtype) if meta.dtype in ("bfloat16", "float16") else torch.float32
        self._cast = self._device.type != "cpu" or self._dtype != torch.float32
        self._graphs = CudaGraphs(module, self._dtype) if meta.extra.get("cuda_graph") else None

    def _run(self, batch: np.ndarray) -> np.ndarray:
        if self._graphs is not None and (replayed := self._graphs.run(batch)) is not None:
            return replayed
        inputs = self._torch.from_numpy(batch)
        with self._torch.inference_mode():
            if self._cast:
                # to the device first, then cast: torch casts a blocking copy to the GPU on the CPU, with
                # every intra-op thread (on an H200 host, fp16's timing kept 16 cores busy; fp32's one)
                return self._module(inputs.to(self._device).to(self._dtype)).float().cpu().numpy()
            return self._module(inputs).numpy()


class CudaGraphs:
    """A CUDA module replayed as one CUDA graph per batch size (captured at that size's first call):
    one launch instead of one per layer. The graph reads and writes fixed tensors on the GPU; a call
    copies the float32 batch in (the cast to the network's precision is in the graph: torch would cast
    a copy to the GPU on the CPU), replays, and copies the float32 output back. One caller at a time (the
    buffers are shared), as a predictor is used."""
    MAX_SIZES = 8    # beyond these, run() answers None: the caller runs the module as it is (a graph holds buffers)

    def __init__(self, module, dtype):
        import torch
        self._torch, self._module, self._dtype = torch, module, dtype
        self._graphs: dict[tuple, tuple[Any, Any, Any]] = {}   # shape -> (input, output, graph)

    def run(self, batch: np.ndarray) -> np.ndarray | None:
        torch = self._torch
        if batch.shape not in self._graphs:
            if len(self._graphs) >= self.MAX_SIZES:
                return None
            try:
                self._graphs[batch.shape] = self._capture(batch.shape)
            except RuntimeError as error:   # torch's error for work that a capture cannot record
                raise PilotlabError(f"cuda_graph: the network could not be captured as a CUDA graph at input shape "
                                    f"{list(batch.shape)} ({library_message(error)}); use the fp16 strategy "
                                    "for this network") from None
        inputs, outputs, graph = self._graphs[batch.shape]
        inputs.copy_(torch.from_numpy(batch))
        graph.replay()
        return outputs.cpu().numpy()

    def _capture(self, shape: tuple) -> tuple[Any, Any, Any]:
        torch = self._torch
        inputs = torch.zeros(shape, device="cuda", dtype=torch.float32)
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.no_grad():
            with torch.cuda.stream(side):   # warm-up off the capture (TorchScript optimises on its first runs)
                for _ in range(3):
                    self._module(inputs.to(self._dtype))
            torch.cuda.current_stream().wait_stream(side)
            graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(graph):
                outputs = self._module(inputs.to(self._dtype)).float()
        return inputs, outputs, graph


class OnnxPredictor(Predictor):
    """An ONNX model run by ONNX Runtime."""

    def __init__(self, meta: ArtifactMeta, hardware: HardwareProfile, session):
        super().__init__(meta, hardware)
        self.session = session
        self._run_session = session.run
        self._outputs = [OUTPUT_NAME]

    def _run(self, batch: np.ndarray) -> np.ndarray:
        return self._run_session(self._outputs, {INPUT_NAME: batch})[0]


class LiteRTPredictor(Predictor):
    """A .tflite model on the LiteRT interpreter (XNNPACK on the CPU). The interpreter is resized
    when the batch size changes. An integer-only model (int8 input and output) gets the image
    quantized and (v, w) dequantized with the scales stored in it, as a deployment must."""

    def __init__(self, meta: ArtifactMeta, hardware: HardwareProfile, interpreter):
        super().__init__(meta, hardware)
        self.interpreter = interpreter
        inp, out = interpreter.get_input_details()[0], interpreter.get_output_details()[0]
        self._input, self._output, self._batch = inp["index"], out["index"], None
        self._quantize = inp["quantization"] if inp["dtype"] == np.int8 else None
        self._dequantize = out["quantization"] if out["dtype"] == np.int8 else None

    def _run(self, batch: np.ndarray) -> np.ndarray:
        if len(batch) != self._batch:
            self.interpreter.resize_tensor_input(self._input, list(batch.shape))
            self.interpreter.allocate_tensors()
            self._batch = len(batch)
        if self._quantize:
            scale, zero = self._quantize
            batch = np.clip(np.round(batch / scale) + zero, -128, 127).astype(np.int8)
        self.interpreter.set_tensor(self._input, batch)
        self.interpreter.invoke()
        output = self.interpreter.get_tensor(self._output)
        if self._dequantize:
            scale, zero = self._dequantize
            return (output.astype(np.float32) - zero) * np.float32(scale)
        return output


def resolve_profile(hardware: HardwareProfile | dict | str | None) -> HardwareProfile:
    if hardware is None:
        return BUILTIN["cpu"]
    if isinstance(hardware, HardwareProfile):
        return hardware
    if isinstance(hardware, dict):
        return profile_from_dict(hardware)
    return make_profile(hardware)


def load_predictor(artifact_dir: Path, hardware: HardwareProfile | dict | str | None = None, *,
                   spin: bool = True) -> Predictor:
    """Load the artifact in `artifact_dir` to run on `hardware` (threads applied to this process).

    `spin=False` stops ONNX Runtime's worker threads from busy-waiting between calls: needed when the
    predictor shares the CPU with other work (the simulator in a closed loop), where spinning threads
    would steal its cores; timing benchmarks keep the default."""
    artifact_dir = Path(artifact_dir)
    meta = read_meta(artifact_dir)
    profile = resolve_profile(hardware)
    if meta.device == "cuda" and profile.device != "cuda":
        raise NotApplicable(f"artifact {meta.strategy} was built for CUDA; hardware {profile.name!r} is a CPU")
    if meta.runtime in EDGE_RUNTIMES:
        _check_edge(meta, profile)
    apply_profile(profile)
    path = artifact_dir / meta.file
    if meta.runtime == "onnxruntime":
        return OnnxPredictor(meta, profile, _ort_session(path, meta, profile, spin))
    if meta.runtime == "torch":
        return TorchPredictor(meta, profile, _torch_module(path, meta, profile))
    if meta.runtime in EDGE_RUNTIMES:
        return _edge_predictor(path, meta, profile)
    raise PilotlabError(f"{artifact_dir}: unknown runtime {meta.runtime!r} in artifact.json")


EDGE_RUNTIMES = {"litert": ("ai_edge_litert", "LiteRT")}   # runtime -> (module, name)


def _check_edge(meta: ArtifactMeta, profile: HardwareProfile) -> None:
    """LiteRT artifacts: CPU only (XNNPACK), and only where the runtime is installed."""
    import importlib.util
    module, runtime = EDGE_RUNTIMES[meta.runtime]
    if profile.device != "cpu":
        raise NotApplicable(f"artifact {meta.strategy} runs on {runtime}'s CPU path (XNNPACK); "
                            f"hardware {profile.name!r} is {profile.device}")
    if importlib.util.find_spec(module) is None:
        raise NotApplicable(f"artifact {meta.strategy} needs {runtime} ({module}), not installed here "
                            "(pip install -e '.[edge]')")


def _edge_predictor(path: Path, meta: ArtifactMeta, profile: HardwareProfile) -> Predictor:
    from ai_edge_litert.interpreter import Interpreter
    return LiteRTPredictor(meta, profile, Interpreter(model_path=str(path), num_threads=profile.cpu_threads))


def _torch_module(path: Path, meta: ArtifactMeta, profile: HardwareProfile):
    import torch
    if meta.format == "torchscript":
        try:
            module = torch.jit.load(str(path), map_location=profile.device)
        except Exception as error:  # torch raises RuntimeError/ValueError/... for a bad archive
            first = library_message(error)
            raise PilotlabError(f"{path}: not a readable TorchScript file ({type(error).__name__}: {first})") from None
    elif meta.format == "pilotlab-checkpoint":
        from pilotlab.models import load_checkpoint
        module, _ = load_checkpoint(path)
    else:
        raise PilotlabError(f"{path}: format {meta.format!r} cannot run on torch")
    return module.to(profile.device).eval()


def check_onnx_file(path: Path) -> None:
    """An ONNX file that ONNX Runtime may load: readable, and any weights it keeps in external files
    inside its own folder (a location such as ../../etc/x would make the runtime read outside)."""
    from pilotlab.models.onnx_data import external_data_files, load_without_data
    external_data_files(load_without_data(path), path, "the artifact's folder")


def _ort_session(path: Path, meta: ArtifactMeta, profile: HardwareProfile, spin: bool = True):
    import onnxruntime
    check_onnx_file(path)
    options = onnxruntime.SessionOptions()
    if not spin:
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    options.graph_optimization_level = onnxruntime.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.execution_mode = onnxruntime.ExecutionMode.ORT_SEQUENTIAL
    options.intra_op_num_threads = profile.cpu_threads
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    providers = _providers(meta, profile)   # outside the try: a missing provider is "not applicable"
    try:
        session = onnxruntime.InferenceSession(str(path), options, providers=providers)
    except Exception as error:  # onnxruntime raises its own Fail/InvalidGraph/... for a bad model
        first = library_message(error)
        raise PilotlabError(f"{path}: ONNX Runtime cannot load it ({type(error).__name__}: {first})") from None
    _check_first_provider(session, providers, meta)
    return session


def _check_first_provider(session, providers: list[Any], meta: ArtifactMeta) -> None:
    """ONNX Runtime falls back to the next provider when the first cannot start (TensorRT's libraries
    missing, say): the artifact would be timed as what it is not."""
    wanted = providers[0] if isinstance(providers[0], str) else providers[0][0]
    running = session.get_providers()[0]
    if running != wanted:
        raise NotApplicable(f"artifact {meta.strategy}: ONNX Runtime could not start {wanted} here and fell back to "
                            f"{running}; install what {wanted} needs (TensorRT's libraries for TensorRT)")


def _providers(meta: ArtifactMeta, profile: HardwareProfile) -> list[Any]:
    import onnxruntime
    if profile.device == "cpu":
        return ["CPUExecutionProvider"]
    wanted = meta.extra.get("providers", ["CUDAExecutionProvider"])
    available = onnxruntime.get_available_providers()
    missing = [p for p in wanted if p not in available]
    if missing:
        build = "onnxruntime-gpu with TensorRT" if "TensorrtExecutionProvider" in missing else "onnxruntime-gpu"
        raise NotApplicable(f"artifact {meta.strategy} needs ONNX Runtime provider(s) {', '.join(missing)} "
                            f"for {profile.name!r}; this onnxruntime has {', '.join(available)} "
                            f"(install {build} in place of onnxruntime)")
    options = {"TensorrtExecutionProvider": {"trt_fp16_enable": bool(meta.extra.get("trt_fp16")),
                                             "trt_int8_enable": bool(meta.extra.get("trt_int8"))}}
    return [(p, options.get(p, {})) for p in wanted] + ["CPUExecutionProvider"]
