"""Stem subsampling, an option of channel pruning: the second convolution keeps only its even kernel taps,
so every other output of the first convolution is never read and the first one runs at twice its stride.

`convolutions: 2` does it once more one layer down (the second convolution at stride 2, the third at its
even taps: a 3×3 kernel at stride 1 over it), with the same effect on the third convolution's inputs.

Why: once channels are pruned, the first convolution is what is left of a CPU's time (it reads the whole
3×66×200 image whatever its width, and its 3 input channels cannot be cut; docs/strategies.md). PilotNet's
first two layers are 5×5 convolutions at stride 2. Zeroing the second one's odd taps (rows and columns 1
and 3 of its 5×5 kernel) leaves a 3×3 kernel at dilation 2 over the first one's output, which reads only
its even rows and columns: the same function as a first convolution at stride 4 followed by a 3×3
convolution at stride 1. Its receptive field (13×13 pixels at a stride of 4) and output shape stay the
same, at any input size (the even rows the second reads are exactly the rows of the first at twice its
stride); the first layer does a quarter of its work and the second 9/25 of its own. The rewrite is exact for
the tap-pruned network (checked against it, as channel removal is); the fine-tune that follows recovers
what the dropped taps carried.

    taps = subsample_stem(model, input_shape, 2)  # in place; each follower's kept kernel: [[3, 3], [3, 3]]
"""
from __future__ import annotations

import copy

import torch
from torch import nn

from matrix.kinds import NotApplicable
from pilotlab.strategies.channels import check_same_function, rebuilt, replace
from pilotlab.strategies.common import conv_linear_layers


def subsample_stem(model: nn.Module, input_shape: tuple, convolutions: int = 1) -> list[list[int]]:
    """Rewrite the first `convolutions` convolutions of `model` and the one after each, in place (see the
    module's docstring; 2 does it again one layer down: the second convolution at stride 2, the third at
    its even taps). Returns the kernel each rewritten follower keeps, e.g. [[3, 3], [3, 3]]."""
    pairs = _pairs(model, convolutions)
    tap_pruned = copy.deepcopy(model)
    for _, (name, _) in pairs:
        _zero_odd_taps(tap_pruned.get_submodule(name))
    for (first_name, _), (second_name, second) in pairs:
        first = model.get_submodule(first_name)        # the previous pair's follower, already rewritten
        replace(model, first_name, _restrided(first, tuple(s * 2 for s in first.stride)))
        replace(model, second_name, _even_taps(second))
    check_same_function(model, tap_pruned, input_shape, "subsample_stem")
    return [list(model.get_submodule(name).kernel_size) for _, (name, _) in pairs]


def _pairs(model: nn.Module, convolutions: int) -> list[tuple[tuple[str, nn.Conv2d], tuple[str, nn.Conv2d]]]:
    """The (convolution, follower) pairs to rewrite, if the rewrite holds for them; else NotApplicable."""
    layers = conv_linear_layers(model)[:convolutions + 1]
    if len(layers) < convolutions + 1 or not all(isinstance(m, nn.Conv2d) for _, m in layers):
        raise NotApplicable(f"subsample_stem {convolutions} needs a network whose first {convolutions + 1} "
                            "layers are convolutions")
    for name, conv in layers:
        if conv.padding not in ((0, 0), "valid") or conv.dilation != (1, 1) or conv.groups != 1:
            raise NotApplicable(f"subsample_stem: {name!r} has padding, dilation or groups (it needs plain "
                                "unpadded convolutions)")
    for name, conv in layers[1:]:
        if conv.stride != (2, 2) or any(k % 2 == 0 for k in conv.kernel_size):
            raise NotApplicable(f"subsample_stem: convolution {name!r} has stride {conv.stride} and kernel "
                                f"{conv.kernel_size}; the one after a subsampled layer needs stride 2 and an odd kernel")
    return list(zip(layers, layers[1:]))


def _zero_odd_taps(conv: nn.Conv2d) -> None:
    odd = torch.ones_like(conv.weight, dtype=torch.bool)
    odd[:, :, ::2, ::2] = False
    with torch.no_grad():
        conv.weight[odd] = 0


def _restrided(conv: nn.Conv2d, stride: tuple[int, int]) -> nn.Conv2d:
    return rebuilt(conv, conv.weight.detach(), _bias(conv), stride)


def _even_taps(conv: nn.Conv2d) -> nn.Conv2d:
    return rebuilt(conv, conv.weight.detach()[:, :, ::2, ::2], _bias(conv), (1, 1))


def _bias(conv: nn.Conv2d) -> torch.Tensor | None:
    return conv.bias.detach() if conv.bias is not None else None
