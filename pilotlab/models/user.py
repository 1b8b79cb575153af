"""Models a user brings: their own nn.Module class (with or without a state dict), a TorchScript
file or an ONNX file, turned into a network every pilotlab job can run (configs: imported.py).

Everything here runs when a job runs (never while planning) and checks what it loads, with one-line
errors that start with the recipe key (`models.<name>.network: ...`): the class's constructor
options, weights that do not fit (missing and unexpected keys, the first shape that differs), a
network whose output is not [N, 2] for the preprocessed input, an ONNX file that is not a model.
User weights are read with torch.load(weights_only=True): a state dict is data, never code.
"""
from __future__ import annotations

import hashlib
import inspect
import io
import logging
import re
from pathlib import Path
from typing import Any

import torch
from torch import nn

from pilotlab import usercode
from pilotlab.errors import PilotlabError, library_message
from pilotlab.models.imported import NetworkConfig, OnnxConfig, TorchScriptConfig

ONNX_INPUT, ONNX_OUTPUT = "images", "vw"   # as pilotlab.strategies.artifact names them
SHOWN = 5                                   # keys listed in a message before "(+N more)"

# DeepLearningStudio's PyTorch PilotNet (Formula1-FollowLine/pytorch/PilotNet/utils/pilotnet.py) names its
# layers ln_1, cn_1..cn_5, fc_1..fc_5; pilotlab's PilotNet holds the same layers as input_norm,
# features.{0,2,4,6,8} (a ReLU between) and head.{1,3,5,7,9} (after the Flatten).
DLS_PILOTNET_NAMES = {"ln_1": "input_norm", **{f"cn_{i}": f"features.{2 * (i - 1)}" for i in range(1, 6)},
                      **{f"fc_{i}": f"head.{2 * i - 1}" for i in range(1, 6)}}


# --- the user's class --------------------------------------------------------------------------------

def build_network(config: NetworkConfig) -> nn.Module:
    """The user's network from a checkpoint's config (what load_checkpoint calls)."""
    cls = usercode.load_object(config.network, Path.cwd())
    if config.source_hash and usercode.source_hash(config.network, Path.cwd()) != config.source_hash:
        logging.getLogger("pilotlab.models").warning(
            "%s changed since this checkpoint was written (source sha256 %s, now another): the weights may "
            "not fit; rerun the recipe to retrain", config.network, config.source_hash[:12])
    return construct(cls, config.options, config.network)


def construct(cls: Any, options: dict[str, Any], where: str) -> nn.Module:
    """`cls(**options)`, an nn.Module; options it does not take are named with those it does."""
    if not (isinstance(cls, type) and issubclass(cls, nn.Module)):
        raise PilotlabError(f"{where}: {getattr(cls, '__name__', cls)!r} is not a torch.nn.Module class")
    parameters = inspect.signature(cls).parameters
    takes = [n for n, p in parameters.items() if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    signature = f"{cls.__name__}({', '.join(takes)})"
    if not any(p.kind == p.VAR_KEYWORD for p in parameters.values()):
        if problem := usercode.options_not_taken(cls.__name__, takes, options):
            raise PilotlabError(problem)
    try:
        inspect.signature(cls).bind(**options)
    except TypeError as error:
        raise PilotlabError(f"options: {signature}: {error}") from None
    try:
        return cls(**options)
    except Exception as error:  # noqa: BLE001 — the user's constructor: say where it failed
        raise PilotlabError(f"options: {cls.__name__}({_given(options)}) failed: "
                            f"{usercode.error_line(error, where)}") from None


def _given(options: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in options.items()) or "no options"


def load_weights(model: nn.Module, path: Path) -> None:
    """Load a state dict file into `model`; it must fit exactly. A DeepLearningStudio PilotNet state dict
    loads into pilotlab's PilotNet (its layer names are mapped)."""
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # noqa: BLE001 — torch raises many types for a file it cannot read
        if found := re.search(r"Unsupported global: GLOBAL (\S+)", str(error)):   # e.g. torch.save(model)
            raise PilotlabError(f"{path.name} holds Python objects ({found[1]}), not only tensors (a whole model "
                                "saved with torch.save(model)?), and pilotlab never unpickles objects; save the "
                                "weights with torch.save(model.state_dict(), path) and give that file") from None
        raise PilotlabError(f"{path.name} is not a state dict torch.load(weights_only=True) can read: "
                            f"{_load_problem(error)}") from None
    wrapped = next((key for key in WRAPPING_KEYS if isinstance(state, dict) and isinstance(state.get(key), dict)), None)
    if wrapped is not None:
        state = state[wrapped]                     # a checkpoint that wraps its state dict (PyTorch's tutorials')
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        holds = f" (it holds {_listed([str(k) for k in state])})" if isinstance(state, dict) else ""
        raise PilotlabError(f"{path.name} is not a state dict (a mapping of names to tensors){holds}; save one with "
                            "torch.save(model.state_dict(), path)")
    own, renamed = model.state_dict(), ""
    if not set(state) & set(own) and {k.split(".")[0] for k in state} <= set(DLS_PILOTNET_NAMES):
        state = {DLS_PILOTNET_NAMES[k.split(".")[0]] + k[len(k.split(".")[0]):]: v for k, v in state.items()}
        renamed = " (the file's DeepLearningStudio PilotNet names read as pilotlab's: ln_1 as input_norm, ...)"
    if problem := weights_problem(own, state):
        raise PilotlabError(f"{path.name} does not fit {type(model).__name__}: {problem}{renamed}")
    model.load_state_dict(state)


def _load_problem(error: Exception) -> str:
    """torch.load's own reason, without its advice to load with weights_only=False (which runs the file's
    code: pilotlab never does) where the unpickler names the reason."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(error))
    if found := re.search(r"WeightsUnpickler error:\s*(\S[^\n]*)", text):
        return found[1].strip()
    return text.splitlines()[0] if text else type(error).__name__


# where a checkpoint keeps its state dict: pilotlab's and Lightning's, PyTorch's "saving a general checkpoint"
WRAPPING_KEYS = ("state_dict", "model_state_dict", "model")


def weights_problem(own: dict[str, torch.Tensor], given: dict[str, torch.Tensor]) -> str | None:
    """What keeps `given` from loading into a network whose state dict is `own`, or None."""
    missing, unexpected = [k for k in own if k not in given], [k for k in given if k not in own]
    shapes = [k for k in own if k in given and tuple(own[k].shape) != tuple(given[k].shape)]
    problems = [f"{what} {_listed(keys)}" for what, keys in (("missing keys", missing),
                                                             ("unexpected keys", unexpected)) if keys]
    if shapes:
        key = shapes[0]
        problems.append(f"first shape that differs: {key} is {list(given[key].shape)} in the file, "
                        f"{list(own[key].shape)} in the network")
    return "; ".join(problems) or None


def _listed(keys: list[str]) -> str:
    more = f" (+{len(keys) - SHOWN} more)" if len(keys) > SHOWN else ""
    return ", ".join(keys[:SHOWN]) + more


def check_output(model: nn.Module, input_shape: tuple[int, int, int], what: str) -> None:
    """The network maps a batch [2, C, H, W] (the preprocessed input) to [2, 2]."""
    shape = [2, *input_shape]
    model.eval()
    try:
        with torch.no_grad():
            output = model(torch.zeros(shape))
    except Exception as error:  # noqa: BLE001 — the user's forward: say where it failed
        # a program's (TorchScript, ONNX Runtime) error has no line of the user's, and its reason may
        # follow its first line (ONNX Runtime: "... for the following indices" then "index: 0 Got: 2 ...")
        # (no line of the user's, as a class without forward: the reason alone, `what` starts the message)
        place = (f"{type(error).__name__}: {library_message(error)}" if isinstance(model, _Program)
                 else usercode.error_line(error, ""))
        raise PilotlabError(f"{what} fails on an input {shape} (the preprocessed camera image): {place}") from None
    if not isinstance(output, torch.Tensor):
        pair = isinstance(output, (tuple, list)) and len(output) == 2
        raise PilotlabError(f"{what}'s output for an input {shape} is a {type(output).__name__}; a driving network "
                            "returns one tensor [N, 2] (normalised v, w)"
                            + ("; return torch.stack([v, w], 1)" if pair else ""))
    got = list(output.shape)
    if got != [2, 2]:
        hint = ("check the input size it was built for against `preprocess` (height, width)"
                if len(got) != 2 or got[0] != 2 else "its last layer must give 2 outputs")
        raise PilotlabError(f"{what}'s output for an input {shape} is {got}; a driving network returns "
                            f"[N, 2] (normalised v, w): {hint}")


# --- whole model files -----------------------------------------------------------------------------

class _Program(nn.Module):
    """A model held as the bytes of its file (the `program` buffer), so a checkpoint stays plain data;
    loading a state dict rebuilds it from those bytes."""

    def __init__(self, config):
        super().__init__()
        self.config = config
        self.register_buffer("program", torch.zeros(0, dtype=torch.uint8))

    def load_program(self, data: bytes) -> _Program:
        self.program = torch.frombuffer(bytearray(data), dtype=torch.uint8)
        self._build(data)
        return self

    def load_state_dict(self, state_dict, strict: bool = True, assign: bool = False):
        return self.load_program(state_dict["program"].cpu().numpy().tobytes())

    def state_dict(self, *args, destination=None, prefix: str = "", keep_vars: bool = False):
        """The program alone: its bytes hold the weights (a TorchScript module's parameters, the module
        being a submodule, would store them a second time: the checkpoint, whose size the report shows,
        twice the file's)."""
        destination = {} if destination is None else destination
        destination[prefix + "program"] = self.program if keep_vars else self.program.detach()
        return destination

    def _build(self, data: bytes) -> None:
        raise NotImplementedError


class TorchScriptModel(_Program):
    """A TorchScript model (torch.jit.save), run as it is."""

    def _build(self, data: bytes) -> None:
        self.module = torch.jit.load(io.BytesIO(data), map_location="cpu").eval()

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.module(images)


class OnnxModel(_Program):
    """An ONNX model run by ONNX Runtime behind a torch forward (for training-side checks and the
    checkpoint); the ONNX strategies use `program`, the graph itself (input `images` NCHW, output `vw`)."""

    def _build(self, data: bytes) -> None:
        import onnxruntime
        options = onnxruntime.SessionOptions()
        options.log_severity_level = 3
        self.session = onnxruntime.InferenceSession(data, options, providers=["CPUExecutionProvider"])

    @property
    def onnx_bytes(self) -> bytes:
        return self.program.cpu().numpy().tobytes()

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        batch = images.detach().cpu().float().contiguous().numpy()
        return torch.from_numpy(self.session.run([ONNX_OUTPUT], {ONNX_INPUT: batch})[0])


def read_torchscript(path: Path) -> bytes:
    data = path.read_bytes()
    try:
        torch.jit.load(io.BytesIO(data), map_location="cpu")
    except Exception as error:  # noqa: BLE001
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        if "zip archive" in first:   # (miniz goes on about checkpoints being corrupted in transfer)
            first = first.split(". ")[0] + " (a TorchScript file is the zip archive torch.jit.save writes)"
        raise PilotlabError(f"{path.name} is not a TorchScript model torch.jit.load can read: {first}") from None
    return data


def read_onnx(path: Path, input_shape: tuple[int, int, int]) -> bytes:
    """The ONNX model with its input renamed `images` (NCHW float32; an NHWC model, as TensorFlow
    exports them, gets a Transpose in front) and its output `vw`."""
    import onnx
    from onnx.external_data_helper import load_external_data_for_model
    from pilotlab.models.onnx_data import external_data_files
    try:
        model = onnx.load_from_string(path.read_bytes())
    except Exception as error:  # noqa: BLE001 — protobuf raises its own types
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise PilotlabError(f"{path.name} is not an ONNX model ({first})") from None
    if external_data_files(model, path, "the model file's folder"):  # read beside the model, into the bytes
        load_external_data_for_model(model, str(path.parent))
    try:
        onnx.checker.check_model(model)
    except Exception as error:  # noqa: BLE001 — the checker raises its own types
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise PilotlabError(f"{path.name} is not an ONNX model ({first})") from None
    graph = model.graph
    if _names(graph) & {ONNX_INPUT, ONNX_OUTPUT}:   # already named as pilotlab names them: free the names
        onnx.compose.add_prefix_graph(graph, USER_PREFIX, inplace=True)
    initializers = {i.name for i in graph.initializer}
    inputs = [i for i in graph.input if i.name not in initializers]
    if len(inputs) != 1 or len(graph.output) != 1:
        raise PilotlabError(f"{path.name}: a driving network has one input (the image) and one output (v, w); "
                            f"this graph has {len(inputs)} and {len(graph.output)}")
    _rename_io(graph, inputs[0], _layout(inputs[0], input_shape, path))
    return model.SerializeToString()


USER_PREFIX = "user/"   # on a graph's names where they are pilotlab's own (images, vw)


def _names(graph) -> set[str]:
    """Every tensor name in the (top-level) graph."""
    names = {v.name for v in (*graph.input, *graph.output, *graph.initializer, *graph.value_info)}
    return names.union(*({*node.input, *node.output} for node in graph.node))


def _layout(value_info, input_shape: tuple[int, int, int], path: Path) -> str:
    dims = [d.dim_value or None for d in value_info.type.tensor_type.shape.dim]
    channels, height, width = input_shape
    name = value_info.name.removeprefix(USER_PREFIX)   # the name in the user's file (outside test: 'user/images')
    if dims and dims[0] is not None:   # torch.onnx.export's default: the graph fixed at the example's batch
        raise PilotlabError(
            f"{path.name}: its input {name!r} has a fixed batch size of {dims[0]} ({dims}); pilotlab "
            "runs a network at batch 1 in a lap and on batches of 64 to evaluate it, so export it with a dynamic "
            "batch axis: torch.onnx.export(model, example, path, input_names=['images'], output_names=['vw'], "
            "dynamic_axes={'images': {0: 'batch'}, 'vw': {0: 'batch'}}), or with dynamo=True, "
            "dynamic_shapes=({0: torch.export.Dim('batch')},)")
    if len(dims) == 4 and dims[1:] in ([height, width, channels],) and dims[3] != dims[1]:
        return "NHWC"
    if len(dims) != 4:
        raise PilotlabError(f"{path.name}: its input {name!r} has {len(dims)} dimensions; an image "
                            f"batch has 4 ([N, {channels}, {height}, {width}] or [N, {height}, {width}, {channels}])")
    return "NCHW"


def _rename_io(graph, image_input, layout: str) -> None:
    import onnx
    from onnx import TensorProto, helper
    original_in, original_out = image_input.name, graph.output[0].name
    dims = [d.dim_value or d.dim_param or "batch" for d in image_input.type.tensor_type.shape.dim]
    nchw = [dims[0], dims[3], dims[1], dims[2]] if layout == "NHWC" else dims
    graph.input.remove(image_input)
    graph.input.insert(0, helper.make_tensor_value_info(ONNX_INPUT, TensorProto.FLOAT, nchw))
    first = (helper.make_node("Transpose", [ONNX_INPUT], [original_in], perm=[0, 2, 3, 1]) if layout == "NHWC"
             else helper.make_node("Identity", [ONNX_INPUT], [original_in]))
    graph.node.insert(0, first)
    graph.node.append(helper.make_node("Identity", [original_out], [ONNX_OUTPUT]))
    out = graph.output[0]
    graph.output.remove(out)
    graph.output.append(onnx.ValueInfoProto(name=ONNX_OUTPUT, type=out.type))


# --- the train job's side --------------------------------------------------------------------------

def sha256_of(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def user_model(spec, files: dict[str, Path], input_shape: tuple[int, int, int], where: str
               ) -> tuple[nn.Module, str, Any, dict[str, Any]]:
    """(network, checkpoint arch, its config, where it came from) for a model spec whose source is
    network, torchscript or onnx. `files` are the job's inputs (network_source, weights, torchscript,
    onnx); every error starts with `where` (models.<name>)."""
    channels, height, width = input_shape
    source = spec.source
    if source == "network":
        return _network(spec, files, input_shape, where)
    path = files[source]
    try:
        if source == "torchscript":
            config = TorchScriptConfig(file=str(path), sha256=sha256_of(path), channels=channels,
                                       height=height, width=width)
            model = TorchScriptModel(config).load_program(read_torchscript(path))
        else:
            config = OnnxConfig(file=str(path), sha256=sha256_of(path), channels=channels, height=height, width=width)
            model = OnnxModel(config).load_program(read_onnx(path, input_shape))
    except PilotlabError as error:
        raise PilotlabError(f"{where}.{source}: {error}") from None
    check_output(model, input_shape, f"{where}.{source}: {Path(path).name}")
    return model, source, config, {"kind": source, "file": getattr(spec, source), "sha256": config.sha256}


def _network(spec, files: dict[str, Path], input_shape: tuple[int, int, int], where: str):
    file = files["network_source"]
    name = spec.network.rpartition(":")[2]
    network = f"{file}:{name}"
    base = file.parent
    try:
        cls = usercode.load_object(network, base)
    except PilotlabError as error:
        raise PilotlabError(f"{where}.network: {error}") from None
    try:
        model = construct(cls, spec.options, str(file))
    except PilotlabError as error:
        raise PilotlabError(f"{where}.{error}" if str(error).startswith("options:") else f"{where}.network: {error}") \
            from None
    if spec.weights is not None:
        try:
            load_weights(model, files["weights"])
        except PilotlabError as error:
            raise PilotlabError(f"{where}.weights: {error}") from None
    check_output(model, input_shape, f"{where}.network: {name}")
    digest = usercode.source_hash(network, base)
    config = NetworkConfig(network=network, options=dict(spec.options), source_hash=digest,
                           channels=input_shape[0], height=input_shape[1], width=input_shape[2])
    origin = {"kind": "network", "file": spec.network, "sha256": digest}
    if spec.weights is not None:
        origin.update(weights=spec.weights, weights_sha256=sha256_of(files["weights"]))
    return model, "network", config, origin


def builtin_weights(model: nn.Module, path: Path, where: str) -> dict[str, Any]:
    """Load a state dict into a built-in arch (a DLS PilotNet one included); where it came from."""
    try:
        load_weights(model, path)
    except PilotlabError as error:
        raise PilotlabError(f"{where}.weights: {error}") from None
    return {"weights": str(path.name), "weights_sha256": sha256_of(path)}
