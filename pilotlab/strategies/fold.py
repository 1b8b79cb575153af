"""Fold an input BatchNorm into the convolution it feeds (PilotNet normalises its input so).

Exact when the convolution has no padding (a padded border would see the un-normalised zero),
and done on a copy before export: one fewer pass over the image at run time, and no batch-norm
left for torchao's QAT conv-bn folding search, which otherwise re-traces ~100 patterns (80 s).
A network without that pattern is returned unchanged.
"""
from __future__ import annotations

import copy

import torch
from torch import fx, nn


def fold_input_norm(model: nn.Module) -> nn.Module:
    try:
        graph = fx.symbolic_trace(model).graph
    except Exception:  # noqa: BLE001 — untraceable networks just keep their batch-norm
        return model
    modules = dict(model.named_modules())
    for node in graph.nodes:
        pair = _norm_then_conv(node, modules)
        if pair:
            folded = copy.deepcopy(model)
            norm_name, conv_name = pair
            _fold(folded.get_submodule(norm_name), folded.get_submodule(conv_name))
            _set(folded, norm_name, nn.Identity())
            return folded
    return model


def _norm_then_conv(node: fx.Node, modules: dict) -> tuple[str, str] | None:
    if node.op != "call_module" or not isinstance(modules.get(node.target), nn.BatchNorm2d):
        return None
    users = list(node.users)
    if len(users) != 1 or users[0].op != "call_module":
        return None
    conv = modules.get(users[0].target)
    if not isinstance(conv, nn.Conv2d) or conv.groups != 1 or any(conv.padding) or conv.padding_mode != "zeros":
        return None
    return node.target, users[0].target


@torch.no_grad()
def _fold(norm: nn.BatchNorm2d, conv: nn.Conv2d) -> None:
    scale = norm.weight / torch.sqrt(norm.running_var + norm.eps)        # per input channel
    shift = norm.bias - norm.running_mean * scale
    bias = conv.bias if conv.bias is not None else torch.zeros(conv.out_channels)
    new_bias = bias + (conv.weight * shift[None, :, None, None]).sum(dim=(1, 2, 3))
    conv.weight.mul_(scale[None, :, None, None])
    conv.bias = nn.Parameter(new_bias)


def _set(model: nn.Module, name: str, module: nn.Module) -> None:
    parent, _, child = name.rpartition(".")
    setattr(model.get_submodule(parent) if parent else model, child, module)
