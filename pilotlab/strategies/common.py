"""Helpers shared by strategy handlers: fine-tuning on the training frames, saving a float model,
sparsity. Handlers only import it (configs never do), so it imports torch at its top."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch
from torch import nn

from matrix.kinds import NotApplicable
from pilotlab.errors import PilotlabError
from pilotlab.hardware import check_available
from pilotlab.models import make_config, save_checkpoint
from pilotlab.strategies.artifact import FLOAT_FORMATS
from pilotlab.strategies.configs.checks import check_distill
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import export_onnx, save_torchscript
from pilotlab.training import FitConfig, fit


def finetune(model: nn.Module, source: StrategySource, *, epochs: int, lr: float,
             batch_size: int, distill: float = 0.0, fake_quant: bool = False) -> list[dict]:
    """Fine-tune in place on the training frames with the shared loop; [] when epochs == 0.

    `distill` > 0 is knowledge distillation from the trained baseline: the loss is
    (1 - distill) · MSE(labels) + distill · MSE(the baseline's outputs), its outputs the soft targets.
    With an MSE loss that is, gradient for gradient, MSE against the blended target
    (1 - distill) · label + distill · baseline output, so the fine-tune trains on frames relabelled so
    (fine-tuning augments nothing, so the baseline's output on each frame is computed once).

    It trains in the precision the model was trained in (pilotlab.training: bf16 mixed precision where
    the CPU has it), except with `fake_quant` (QAT): its fake quantization emulates int8 arithmetic,
    which a bfloat16 forward pass would round again, so QAT fine-tunes in fp32."""
    if epochs <= 0:
        return []
    source.log.info("fine-tuning %d epoch(s) on %d frames%s", epochs, len(source.calibration),
                    f", distilling the baseline (weight {distill:g})" if distill else "")

    def on_epoch(row: dict) -> None:
        source.progress(row["epoch"], epochs, f"fine-tune epoch {row['epoch']}/{epochs}")
    config = FitConfig(epochs=epochs, batch_size=batch_size, lr=lr, frames=source.frames,
                       precision="fp32" if fake_quant else source.training_precision)
    data = soft_targets(source, distill) if distill else source.calibration
    return fit(model, data, source.labels, config, on_epoch=on_epoch)


def soft_targets(source: StrategySource, distill: float):
    """The training frames with labels (1 - distill) · label + distill · the trained baseline's output."""
    check_distill(distill)
    data, teacher = source.calibration, source.load_model().eval()
    with torch.no_grad():
        outputs = np.concatenate([teacher(inputs).numpy() for inputs, _ in data.batches(256, frames=source.frames)])
    soft = source.labels.denormalise(outputs)
    labels = ((1 - distill) * np.asarray(data.labels, np.float32) + distill * soft).astype(np.float32)
    return dataclasses.replace(data, labels=labels, meta={**data.meta, "distill": distill})


def save_float_model(model: nn.Module, source: StrategySource, fmt: str,
                     extra: dict | None = None, *, same_arch: bool = True) -> None:
    """Save a float32 model as a pilotlab checkpoint (eager, as the 2022 study ran its pruned
    models), TorchScript or ONNX, and write artifact.json."""
    model = model.eval()
    if fmt not in FLOAT_FORMATS:
        raise PilotlabError(f"format: {fmt!r} is not one of {', '.join(FLOAT_FORMATS)}")
    if fmt == "checkpoint":
        if not same_arch:
            raise PilotlabError("format: 'checkpoint' cannot hold a network whose "
                                "layers changed shape; use format: torchscript or onnx")
        write_checkpoint(model, source)
        meta = source.meta(format="pilotlab-checkpoint", file="model.pt", runtime="torch",
                           dtype="float32", extra=extra)
    elif fmt == "torchscript":
        save_torchscript(model, source.out / "model.ts", source.input_shape)
        meta = source.meta(format="torchscript", file="model.ts", runtime="torch",
                           dtype="float32", extra=extra)
    else:
        export_onnx(model, source.out / "model.onnx", source.input_shape)
        meta = source.meta(format="onnx", file="model.onnx", runtime="onnxruntime",
                           dtype="float32", extra=extra)
    source.write(meta)


def write_checkpoint(model: nn.Module, source: StrategySource) -> Path:
    """The model as a pilotlab checkpoint with the original arch, config, labels and preprocess."""
    checkpoint = source.checkpoint
    config = make_config(checkpoint["arch"], checkpoint["config"])
    extra = {k: v for k, v in checkpoint.items() if k not in ("format", "arch", "config", "state_dict")}
    path = source.out / "model.pt"
    save_checkpoint(path, model, checkpoint["arch"], config, **extra)
    return path


def conv_linear_layers(model: nn.Module) -> list[tuple[str, nn.Module]]:
    """Every Conv2d and Linear of `model`, in registration order (none for a TorchScript program)."""
    return [(name, m) for name, m in model.named_modules() if isinstance(m, (nn.Conv2d, nn.Linear))]


def weight_layers(model: nn.Module) -> list[tuple[str, nn.Module]]:
    """The layers pruning and clustering act on: every Conv2d and Linear, in registration order; a model
    with none is an error (nothing to rewrite; on a model the user brought, the strategy is not applicable)."""
    layers = conv_linear_layers(model)
    if not layers:
        raise LookupError(f"the model ({type(model).__name__}) has no nn.Conv2d or nn.Linear layer to act on")
    return layers


def sparsity_report(model: nn.Module) -> dict:
    """Fraction of exactly-zero weights, overall and per layer (conv/linear weights, not biases)."""
    layers = {name: m.weight.detach() for name, m in weight_layers(model)}
    zeros = {name: int((w == 0).sum()) for name, w in layers.items()}
    total = sum(w.numel() for w in layers.values())
    params = sum(p.numel() for p in model.parameters())
    nonzero = sum(int((p != 0).sum()) for p in model.parameters())
    return {"sparsity": sum(zeros.values()) / total, "params": params, "nonzero_params": nonzero,
            "layer_sparsity": {name: zeros[name] / layers[name].numel() for name in layers}}



def require_cuda_target(source: StrategySource) -> None:
    """NotApplicable unless the optimize job targets a CUDA profile and this host has the GPU."""
    if source.hardware.device != "cuda":
        # (one optimize job serves every CPU profile: it cannot name the one of the cell)
        raise NotApplicable(f"{source.strategy} runs on a CUDA hardware target, not on a CPU profile")
    check_available(source.hardware)
