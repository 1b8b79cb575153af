"""PyTorch int8: `static_quant` (post-training, calibrated on training frames) and `qat`
(quantization-aware fine-tuning, then convert) — the study's torch.ao strategies on torch 2.13.

Why this path: eager/FX `torch.ao.quantization` is deprecated in torch 2.13 and
`torch.ao.quantization.quantize_pt2e` is gone; its maintained successor is torchao's PT2E flow
(torch.export -> prepare_pt2e / prepare_qat_pt2e with the X86 quantizer -> convert_pt2e). Its
output is a graph of quantize/dequantize ops around fp32 ops that only becomes fast when a backend
lowers it; torch.compile's lowering cannot be saved, so we export that graph to ONNX (QDQ) and let
ONNX Runtime run the int8 kernels. Weights are int8 per output channel (the X86 quantizer's
default), activations uint8 per tensor, all scales learnt in PyTorch.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import torch
from torch import nn

from pilotlab.strategies.artifact import export_onnx
from pilotlab.strategies.common import finetune
from pilotlab.strategies.registry import StrategySource, register_strategy


@dataclass(frozen=True)
class StaticQuantConfig:
    version: int = 1
    calibration_frames: int = 512


@register_strategy("static_quant", StaticQuantConfig)
def static_quant(config: StaticQuantConfig, source: StrategySource) -> dict:
    from torchao.quantization.pt2e.quantize_pt2e import convert_pt2e, prepare_pt2e
    prepared = prepare_pt2e(export_graph(source.load_model(), source.input_shape), x86_quantizer(qat=False))
    with torch.no_grad():
        for batch in source.calibration_batches(config.calibration_frames):
            prepared(batch)
    save_quantized(convert_pt2e(prepared), source, "static_quant")
    return {"calibration_frames": min(config.calibration_frames, len(source.calibration))}


@dataclass(frozen=True)
class QatConfig:
    version: int = 1
    calibration_frames: int = 256    # observed before fine-tuning, so ranges start calibrated
    finetune_epochs: int = 2
    lr: float = 1e-4
    batch_size: int = 64


@register_strategy("qat", QatConfig)
def qat(config: QatConfig, source: StrategySource) -> dict:
    history = quantization_aware_finetune(source.load_model(), source, config, "qat")
    return {"finetune": history}


def quantization_aware_finetune(model: nn.Module, source: StrategySource, config, strategy: str,
                                keep_zeros: bool = False) -> list[dict]:
    """Insert fake-quant, fine-tune, convert, save. `keep_zeros` keeps pruned weights at zero."""
    from torchao.quantization.pt2e.quantize_pt2e import convert_pt2e, prepare_qat_pt2e
    prepared = prepare_qat_pt2e(export_graph(model.train(), source.input_shape), x86_quantizer(qat=True))
    with torch.no_grad():   # start from calibrated ranges (and have ranges even with 0 epochs)
        for batch in source.calibration_batches(config.calibration_frames):
            prepared(batch)
    if keep_zeros:
        freeze_zeros(prepared)
    trainable = _TrainEvalSwitch(prepared)
    history = finetune(trainable, source, epochs=config.finetune_epochs, lr=config.lr,
                       batch_size=config.batch_size)
    trainable.eval()
    save_quantized(convert_pt2e(prepared), source, strategy)
    return history


def export_graph(model: nn.Module, input_shape: tuple) -> torch.fx.GraphModule:
    # A batch-2 example: torch.export specialises a batch of 1, and we want any batch size.
    from pilotlab.strategies.artifact import example_batch
    from pilotlab.strategies.fold import fold_input_norm
    model = fold_input_norm(model)
    batch = torch.export.Dim("batch", min=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return torch.export.export(model, (example_batch(input_shape),), dynamic_shapes=({0: batch},)).module()


def x86_quantizer(qat: bool):
    import torchao.quantization.pt2e.quantizer.x86_inductor_quantizer as x86
    return x86.X86InductorQuantizer().set_global(x86.get_default_x86_inductor_quantization_config(is_qat=qat))


def save_quantized(converted: torch.fx.GraphModule, source: StrategySource, strategy: str) -> None:
    from torchao.quantization.pt2e import move_exported_model_to_eval
    move_exported_model_to_eval(converted)
    export_onnx(converted, source.out / "model.onnx", source.input_shape)
    source.write(source.meta(strategy, format="onnx", file="model.onnx", runtime="onnxruntime", dtype="int8",
                             extra={"quantizer": "torchao pt2e X86InductorQuantizer",
                                    "weights": "int8 per channel", "activations": "uint8 per tensor"}))


def freeze_zeros(model: nn.Module) -> None:
    """Zero the gradient of weights that are exactly zero, so fine-tuning keeps a pruned pattern
    (with a zero gradient Adam's update is zero too)."""
    for param in model.parameters():
        if param.dim() >= 2 and bool((param == 0).any()):
            mask = (param != 0).to(param.dtype)
            param.register_hook(lambda grad, mask=mask: grad * mask)


class _TrainEvalSwitch(nn.Module):
    """An exported graph forbids .train()/.eval(); the shared training loop calls them. Switch the
    graph's dropout and batch-norm the way torchao says instead."""

    def __init__(self, graph: torch.fx.GraphModule):
        super().__init__()
        self.graph = graph

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.graph(images)

    def train(self, mode: bool = True) -> _TrainEvalSwitch:
        from torchao.quantization.pt2e import move_exported_model_to_eval, move_exported_model_to_train
        (move_exported_model_to_train if mode else move_exported_model_to_eval)(self.graph)
        self.training = mode
        return self
