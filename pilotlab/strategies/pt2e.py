"""PyTorch int8: `static_quant` (post-training, calibrated on training frames) and `qat`
(quantization-aware fine-tuning, then convert) — the study's torch.ao strategies on torch 2.13.

Why this path: eager/FX `torch.ao.quantization` is deprecated in torch 2.13 and
`torch.ao.quantization.quantize_pt2e` is gone; its maintained successor is torchao's PT2E flow
(torch.export -> prepare_pt2e / prepare_qat_pt2e with the X86 quantizer -> convert_pt2e). Its
output is a graph of quantize/dequantize ops around fp32 ops that only becomes fast when a backend
lowers it; torch.compile's lowering cannot be saved, so we export that graph to ONNX (QDQ) and let
ONNX Runtime run the int8 kernels. Weights are int8 per output channel (the X86 quantizer's
default), activations uint8 per tensor, all scales learnt in PyTorch. Configs: configs/pt2e.py.
"""
from __future__ import annotations

import torch
from torch import nn
from torchao.quantization.pt2e.quantize_pt2e import convert_pt2e, prepare_pt2e, prepare_qat_pt2e

from pilotlab.strategies.common import finetune
from pilotlab.strategies.configs.pt2e import QatConfig, StaticQuantConfig
from pilotlab.strategies.pt2e_graph import (TrainEvalSwitch, export_graph, freeze_zeros, save_quantized,
                                            x86_quantizer)
from pilotlab.strategies.apply import StrategySource


def static_quant(config: StaticQuantConfig, source: StrategySource) -> dict:
    prepared = prepare_pt2e(export_graph(source.load_model(), source.input_shape), x86_quantizer(qat=False))
    with torch.no_grad():
        for batch in source.calibration_batches(config.calibration_frames):
            prepared(batch)
    save_quantized(convert_pt2e(prepared), source)
    return {"calibration_frames": min(config.calibration_frames, len(source.calibration))}


def qat(config: QatConfig, source: StrategySource) -> dict:
    history = quantization_aware_finetune(source.load_model(), source, config)
    return {"finetune": history}


def quantization_aware_finetune(model: nn.Module, source: StrategySource, config,
                                keep_zeros: bool = False) -> list[dict]:
    """Insert fake-quant, fine-tune, convert, save. `keep_zeros` keeps pruned weights at zero."""
    prepared = prepare_qat_pt2e(export_graph(model.train(), source.input_shape), x86_quantizer(qat=True))
    with torch.no_grad():   # start from calibrated ranges (and have ranges even with 0 epochs)
        for batch in source.calibration_batches(config.calibration_frames):
            prepared(batch)
    if keep_zeros:
        freeze_zeros(prepared)
    trainable = TrainEvalSwitch(prepared)
    history = finetune(trainable, source, epochs=config.finetune_epochs, lr=config.lr,
                       batch_size=config.batch_size, fake_quant=True)
    trainable.eval()
    save_quantized(convert_pt2e(prepared), source)
    return history
