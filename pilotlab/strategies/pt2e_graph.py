"""The torch.export graphs of the PT2E flow (pt2e.py): export, the X86 quantizer, saving the
converted graph as ONNX QDQ, and what fine-tuning an exported graph needs."""
from __future__ import annotations

import warnings
from pathlib import Path

import torch
import torchao.quantization.pt2e.quantizer.x86_inductor_quantizer as x86
from torch import nn
from torchao.quantization.pt2e import move_exported_model_to_eval, move_exported_model_to_train

from pilotlab.errors import PilotlabError
from pilotlab.strategies.fold import fold_input_norm
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import example_batch, export_onnx


def export_graph(model: nn.Module, input_shape: tuple) -> torch.fx.GraphModule:
    # A batch-2 example: torch.export specialises a batch of 1, and we want any batch size.
    model = fold_input_norm(model)
    batch = torch.export.Dim("batch", min=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return torch.export.export(model, (example_batch(input_shape),), dynamic_shapes=({0: batch},)).module()


def x86_quantizer(qat: bool) -> x86.X86InductorQuantizer:
    return x86.X86InductorQuantizer().set_global(x86.get_default_x86_inductor_quantization_config(is_qat=qat))


def save_quantized(converted: torch.fx.GraphModule, source: StrategySource) -> None:
    switch_mode(converted, training=False)
    export_onnx(converted, source.out / "model.onnx", source.input_shape)
    check_quantized(source.out / "model.onnx")
    source.write(source.meta(format="onnx", file="model.onnx", runtime="onnxruntime", dtype="int8",
                             extra={"quantizer": "torchao pt2e X86InductorQuantizer",
                                    "weights": "int8 per channel", "activations": "uint8 per tensor"}))


WEIGHTED_OPS = ("Conv", "Gemm", "MatMul")


def check_quantized(path: Path) -> None:
    """An int8 artifact must run its layers in int8: an ONNX graph without a QuantizeLinear/
    DequantizeLinear node would run in float while its row says int8 (a torch/torchao pair whose export
    drops the quantize ops), and so would a layer whose weight is a float tensor (a pattern the quantizer
    did not match): either is an error, naming what is in float."""
    import onnx
    graph = onnx.load(str(path), load_external_data=False).graph
    if not any(node.op_type in ("QuantizeLinear", "DequantizeLinear") for node in graph.node):
        import torchao
        raise PilotlabError(f"{path}: the quantized network was exported without a single quantize or dequantize "
                            f"op, so it would run in float (torch {torch.__version__}, torchao {torchao.__version__}); "
                            "pilotlab's int8 PT2E flow is made for the torch and torchao its pyproject.toml pins")
    if floats := float_weight_layers(graph):
        raise PilotlabError(f"{path}: layer(s) {', '.join(floats)} take float weights, not int8 ones through a "
                            "DequantizeLinear: the quantizer left them unquantized, so the artifact is not the int8 "
                            "network its row would say; use a strategy that keeps layers in float on purpose "
                            "(onnxruntime_int8 keeps the first convolution) or report it as a bug")


def float_weight_layers(graph) -> list[str]:
    """The Conv/Gemm/MatMul nodes whose weight (input 1) is a float constant: a float initializer or
    Constant node, not an int8 one through DequantizeLinear (a MatMul of two activations has no weight)."""
    import onnx
    floats = {onnx.TensorProto.FLOAT, onnx.TensorProto.FLOAT16, onnx.TensorProto.DOUBLE, onnx.TensorProto.BFLOAT16}
    constants = {tensor.name for tensor in graph.initializer if tensor.data_type in floats}
    constants |= {output for node in graph.node if node.op_type == "Constant" for output in node.output
                  if any(a.t.data_type in floats for a in node.attribute if a.name == "value")}
    return [node.name or node.op_type for node in graph.node
            if node.op_type in WEIGHTED_OPS and len(node.input) > 1 and node.input[1] in constants]


def freeze_zeros(model: nn.Module) -> None:
    """Zero the gradient of weights that are exactly zero, so fine-tuning keeps a pruned pattern
    (with a zero gradient Adam's update is zero too)."""
    for param in model.parameters():
        if param.dim() >= 2 and bool((param == 0).any()):
            mask = (param != 0).to(param.dtype)
            param.register_hook(lambda grad, mask=mask: grad * mask)


class TrainEvalSwitch(nn.Module):
    """An exported graph forbids .train()/.eval(); the shared training loop calls them. Switch the
    graph's dropout and batch-norm the way torchao says instead."""

    def __init__(self, graph: torch.fx.GraphModule):
        super().__init__()
        self.graph = graph

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.graph(images)

    def train(self, mode: bool = True) -> TrainEvalSwitch:
        switch_mode(self.graph, training=mode)
        self.training = mode
        return self


MODE_OPS = ("dropout", "batch_norm")    # the only ops torchao's train/eval switch rewrites


def switch_mode(graph: torch.fx.GraphModule, training: bool) -> None:
    """torchao's move_exported_model_to_train/eval, skipped for a graph with no dropout or batch-norm op
    (PilotNet's, its input norm folded): there it changes nothing, yet each switch exports its patterns
    to match them, ~1.3 s of one core; a fine-tune switches twice an epoch."""
    if any(node.op == "call_function" and any(op in str(node.target) for op in MODE_OPS) for node in graph.graph.nodes):
        (move_exported_model_to_train if training else move_exported_model_to_eval)(graph)
