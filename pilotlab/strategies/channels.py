"""Channel surgery for the `structured_prune` strategy: remove the conv channels and linear neurons
that contribute least to the next layer from a chain of layers, checked against the same network with
them zeroed."""
from __future__ import annotations

import copy

import torch
from torch import nn

from matrix.kinds import NotApplicable
from pilotlab.strategies.common import conv_linear_layers, weight_layers
from pilotlab.strategies.saving import example_batch


def remove_channels(model: nn.Module, amount: float, input_shape: tuple, multiple_of: int = 1,
                    sample: torch.Tensor | None = None) -> dict[str, int]:
    """Shrink `model` in place, layer by layer from the input; returns the channels/neurons kept per layer.

    With `sample` (a batch of training frames) a layer keeps the channels whose output reaches the next
    layer most: mean |input of the next layer| from that channel (after the activation, on the network
    as pruned so far) × the L1 norm of the next layer's weights on it. A unit that never fires on the
    data scores 0 however large its weights. Without, a layer keeps the channels of largest L1 weight norm
    (Li et al. 2017), which on the study's PilotNet kept units dead on every frame (3 of the 8 kept in its
    last hidden layer) and its fine-tune collapsed in 3 of 7 frame orders (docs/strategies.md)."""
    check_chain(model)
    layers = weight_layers(model)
    masked = copy.deepcopy(model)
    kept: dict[str, int] = {}
    for (name, _), (next_name, _) in zip(layers, layers[1:]):
        scores = (output_contributions(model, name, next_name, sample) if sample is not None
                  else l1_norms(model.get_submodule(name)))
        keep = strongest(scores, kept_count(len(scores), amount, multiple_of))
        zero_channels(masked.get_submodule(name), keep)
        layer = model.get_submodule(name)           # already shrunk on its inputs
        replace(model, name, shrink_outputs(layer, keep))
        replace(model, next_name, shrink_inputs(model.get_submodule(next_name), keep, layer.weight.shape[0]))
        kept[name] = len(keep)
    check_same_function(model, masked, input_shape)
    return kept


def check_chain(model: nn.Module) -> None:
    """NotApplicable unless the conv/linear layers form one chain (each feeding the next) channels can be cut from."""
    if hasattr(model, "load_program"):   # pilotlab.models.user's TorchScript / ONNX program: no layers to cut
        raise NotApplicable(f"structured_prune removes channels from a PyTorch network's layers; a "
                            f"{type(model).__name__.removesuffix('Model')} model is run as it is (give `network:`, "
                            "the PyTorch class, to prune it)")
    layers = conv_linear_layers(model)
    if len(layers) < 2:
        raise NotApplicable("structured_prune needs at least two conv/linear layers")
    first = next(name for name, _ in layers)
    for name, module in model.named_modules():
        if isinstance(module, nn.modules.batchnorm._BatchNorm) and _registered_after(model, name, first):
            raise NotApplicable(f"structured_prune: batch-norm {name!r} sits inside the layer chain; "
                                "only an input normalisation before the first layer is supported")
    for (name, a), (next_name, b) in zip(layers, layers[1:]):
        if not _feeds(a, b):
            raise NotApplicable(f"structured_prune: layer {name!r} does not feed {next_name!r} directly "
                                "(the conv/linear layers do not form one chain)")


def _registered_after(model: nn.Module, name: str, first: str) -> bool:
    names = [n for n, _ in model.named_modules()]
    return names.index(name) > names.index(first)


def _feeds(a: nn.Module, b: nn.Module) -> bool:
    outputs = a.out_channels if isinstance(a, nn.Conv2d) else a.out_features
    if isinstance(b, nn.Conv2d):
        return isinstance(a, nn.Conv2d) and b.groups == 1 and b.in_channels == outputs
    return b.in_features % outputs == 0 and (isinstance(a, nn.Conv2d) or b.in_features == outputs)


def strongest(scores: torch.Tensor, count: int) -> torch.Tensor:
    """The indices of the `count` highest scores, in channel order."""
    return scores.topk(count).indices.sort().values


def l1_norms(layer: nn.Module) -> torch.Tensor:
    """[out channels]: the L1 norm of each output channel's weights."""
    return layer.weight.detach().abs().flatten(1).sum(1)


def output_contributions(model: nn.Module, name: str, next_name: str, sample: torch.Tensor) -> torch.Tensor:
    """[out channels of `name`]: mean |input of `next_name`| from each channel over `sample` (a linear
    layer after a flatten sees a channel as a block of H×W inputs) × the L1 norm of `next_name`'s weights
    on that channel."""
    channels, following = model.get_submodule(name).weight.shape[0], model.get_submodule(next_name)
    seen: list[torch.Tensor] = []
    hook = following.register_forward_pre_hook(lambda _module, args: seen.append(args[0].detach()))
    try:
        with torch.no_grad():
            model.eval()(sample)
    finally:
        hook.remove()
    activity = seen[0].reshape(len(sample), channels, -1).abs().mean((0, 2))
    weights = following.weight.detach().abs()                       # [out, in] or [out, in, kH, kW]
    return activity * weights.reshape(weights.shape[0], channels, -1).sum((0, 2))


def kept_count(channels: int, amount: float, multiple_of: int = 1) -> int:
    """Channels kept: (1 - amount) of them, rounded to the nearest multiple of `multiple_of` (SIMD
    kernels work on whole blocks, so a partial block costs a full one) or to the layer's own width."""
    count = max(1, round(channels * (1 - amount)))
    if multiple_of == 1 or channels < multiple_of:
        return count
    lower = max(multiple_of, count // multiple_of * multiple_of)
    upper = min(channels, -(-count // multiple_of) * multiple_of)     # the layer's own width caps it
    return upper if upper - count < count - lower else lower


def zero_channels(layer: nn.Module, keep: torch.Tensor) -> None:
    drop = torch.ones(layer.weight.shape[0], dtype=torch.bool)
    drop[keep] = False
    with torch.no_grad():
        layer.weight[drop] = 0
        if layer.bias is not None:
            layer.bias[drop] = 0


def shrink_outputs(layer: nn.Module, keep: torch.Tensor) -> nn.Module:
    weight = layer.weight.detach()[keep]
    bias = layer.bias.detach()[keep] if layer.bias is not None else None
    return rebuilt(layer, weight, bias)


def shrink_inputs(layer: nn.Module, keep: torch.Tensor, channels: int) -> nn.Module:
    """Drop the inputs fed by removed channels; a linear layer after a flatten sees each channel as
    a block of H×W inputs (NCHW order)."""
    weight = layer.weight.detach()
    if isinstance(layer, nn.Linear):
        weight = weight.reshape(weight.shape[0], channels, -1)[:, keep].flatten(1)
    else:
        weight = weight[:, keep]
    bias = layer.bias.detach() if layer.bias is not None else None
    return rebuilt(layer, weight, bias)


def rebuilt(layer: nn.Module, weight: torch.Tensor, bias: torch.Tensor | None,
            stride: tuple[int, int] | None = None) -> nn.Module:
    """`layer` remade around `weight` (its shape gives the channels and, for a conv, the kernel) and `bias`;
    a conv keeps its padding and dilation, and its stride unless `stride` is given."""
    if isinstance(layer, nn.Conv2d):
        new = nn.Conv2d(weight.shape[1], weight.shape[0], tuple(weight.shape[2:]), stride or layer.stride,
                        layer.padding, layer.dilation, bias=bias is not None)
    else:
        new = nn.Linear(weight.shape[1], weight.shape[0], bias=bias is not None)
    with torch.no_grad():
        new.weight.copy_(weight)
        if bias is not None:
            new.bias.copy_(bias)
    return new


def replace(model: nn.Module, name: str, new: nn.Module) -> None:
    parent, _, child = name.rpartition(".")
    setattr(model.get_submodule(parent) if parent else model, child, new)


def check_same_function(model: nn.Module, masked: nn.Module, input_shape: tuple, rewrite: str = "") -> None:
    """NotApplicable unless the rewritten `model` computes what `masked` (the weights zeroed) does."""
    batch = example_batch(input_shape, 4)
    with torch.no_grad():
        expected, actual = masked.eval()(batch), model.eval()(batch)
    if not torch.allclose(expected, actual, rtol=1e-3, atol=1e-5):
        what = f"{rewrite}: the rewritten layers" if rewrite else "structured_prune: removing channels"
        raise NotApplicable(f"{what} changed the network's function (an activation between layers does not "
                            "map 0 to 0, or a layer is used outside the chain?)")


def multiply_accumulates(model: nn.Module, input_shape: tuple) -> int:
    """Multiply-accumulates per image of the conv/linear layers (what bounds CPU inference time)."""
    counts: list[int] = []

    def count(module: nn.Module, _inputs, output) -> None:
        counts.append(output[0].numel() * module.weight[0].numel())   # weight[0]: one output's inputs
    hooks = [m.register_forward_hook(count) for _, m in conv_linear_layers(model)]
    try:
        with torch.no_grad():
            model.eval()(torch.zeros(1, *input_shape[1:]))
    finally:
        for hook in hooks:
            hook.remove()
    return sum(counts)
