"""The torch side of the TF-MOT strategies (mot.py): pruning masks, weight clusters and int8 fake
quantization as `torch.nn.utils.parametrize` parametrizations of each conv/linear weight, so they
stack (mask -> fake-quant for PQAT; clusters -> fake-quant for CQAT; sparse clusters -> fake-quant
for PCQAT), every fine-tuning step sees the constrained weight, and `bake` writes the constrained
weight in.

Fake quantization mimics what the LiteRT converter does afterwards: weights int8 symmetric per
output channel (scale = max|w| / 127, the converter's own choice, so baked weights on that grid
convert to exactly those int8 values), activations int8 per tensor (after each ReLU, the network's
input and output), ranges from min/max on calibration frames then a moving average while training.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.nn.utils import parametrize

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.common import weight_layers
from pilotlab.strategies.configs.prepare import MagnitudePruning
from pilotlab.strategies.fold import fold_input_norm
from pilotlab.strategies.kmeans import kmeans


class Mask(nn.Module):
    """Pruning: the weights outside the mask are zero, and get no gradient."""

    def __init__(self, mask: torch.Tensor):
        super().__init__()
        self.register_buffer("mask", mask)

    def forward(self, weight: torch.Tensor) -> torch.Tensor:
        return weight * self.mask


class Clusters(nn.Module):
    """Weight sharing: every weight is its cluster's centroid; the centroids are what trains, so the
    weights stay on them. `zeros` (pruned weights) take a fixed zero that never trains."""

    def __init__(self, centroids: torch.Tensor, index: torch.Tensor, zeros: torch.Tensor | None = None):
        super().__init__()
        self.centroids = nn.Parameter(centroids.clone())
        index = index.clone()
        if zeros is not None:
            index[zeros.flatten()] = len(centroids)      # the extra, fixed zero
        self.register_buffer("index", index)
        self.register_buffer("zero", torch.zeros(1))

    def forward(self, weight: torch.Tensor) -> torch.Tensor:
        return _in_layout_of(weight, torch.cat([self.centroids, self.zero])[self.index].view_as(weight))


def _in_layout_of(weight: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """`values` in `weight`'s memory layout: fine-tuning runs the convolutions channels-last
    (pilotlab.training), and a conv handed a standard-layout weight there runs ~1.5x slower."""
    return values.contiguous(memory_format=torch.channels_last) if _channels_last(weight) else values


def _channels_last(x: torch.Tensor) -> bool:
    """Laid out channels-last (and not also in the standard layout, as a tensor with 1x1 planes is)."""
    return x.dim() == 4 and not x.is_contiguous() and x.is_contiguous(memory_format=torch.channels_last)


class FakeQuantWeight(nn.Module):
    """int8 symmetric per output channel, as the LiteRT converter quantizes conv and dense weights."""

    def forward(self, weight: torch.Tensor) -> torch.Tensor:
        scale = (weight.detach().abs().flatten(1).amax(1) / 127).clamp(min=1e-12)
        zero = torch.zeros_like(scale, dtype=torch.int32)
        return torch.fake_quantize_per_channel_affine(weight, scale, zero, 0, -127, 127)


class ActivationQuant:
    """A forward (pre-)hook: int8 per tensor on an activation, range observed (min/max while
    calibrating, a moving average while training, frozen in eval)."""

    def __init__(self, momentum: float = 0.01):
        self.low, self.high, self.momentum, self.calibrating = 0.0, 0.0, momentum, False
        self.seen = False

    def quantize(self, x: torch.Tensor, training: bool) -> torch.Tensor:
        low, high = map(float, torch.aminmax(_memory_order(x.detach())))   # one pass, not two
        if self.calibrating or not self.seen:
            self.low, self.high = (min(self.low, low), max(self.high, high)) if self.seen else (min(low, 0.0),
                                                                                                  max(high, 0.0))
            self.seen = True
        elif training:
            self.low += self.momentum * (min(low, 0.0) - self.low)
            self.high += self.momentum * (max(high, 0.0) - self.high)
        if self.calibrating:
            return x
        scale = max(self.high - self.low, 1e-8) / 255
        zero = int(round(-128 - self.low / scale))
        return FakeQuantPerTensor.apply(x, scale, max(-128, min(127, zero)), -128, 127)

    def output_hook(self, module: nn.Module, inputs, output):
        return self.quantize(output, module.training)

    def input_hook(self, module: nn.Module, inputs):
        return (self.quantize(inputs[0], module.training), *inputs[1:])


class FakeQuantPerTensor(torch.autograd.Function):
    """`torch.fake_quantize_per_tensor_affine(x, scale, zero, low, high)`: the same float32 arithmetic
    (x · (1/scale) rounded half to even, clamped, times scale) and the same straight-through gradient
    (none where the value was clamped), equal to it (tests/pilotlab/strategies/test_mot_torch.py), in
    whole-tensor float passes. torch's CPU kernel goes element by element and its backward multiplies
    by a bool mask: 25 ms a step for PilotNet's first activation at a batch of 64 on one thread
    against ~10 here, on a QAT step of ~200 ms."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, scale: float, zero: int, low: int, high: int) -> torch.Tensor:
        scale32 = np.float32(scale)
        steps = (x * float(np.float32(1.0) / scale32)).round_()   # the kernel's float32 1/scale
        clamped = steps.clamp(low - zero, high - zero)
        # 1 where nothing was clamped, else 0: steps and clamped are whole numbers, so they differ by >= 1
        # where they differ (a float mask: torch's bool comparisons and bool products are the slow part)
        ctx.save_for_backward(steps.sub_(clamped).abs_().neg_().add_(1.0).clamp_(min=0.0))
        return clamped.mul_(float(scale32))

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        inside, = ctx.saved_tensors
        return grad * inside, None, None, None, None


def _memory_order(x: torch.Tensor) -> torch.Tensor:
    """The same elements as a view in memory order (a reduction over a channels-last tensor would
    copy it to the standard layout first: 5 ms against 1 on PilotNet's first activation)."""
    return x.permute(0, 2, 3, 1) if _channels_last(x) else x


def fold(model: nn.Module) -> nn.Module:
    """The network as it will be deployed: its input batch-norm folded into the first conv (what the
    export does), so pruning, clustering and QAT act on the weights that reach the artifact."""
    return fold_input_norm(model.eval())


def magnitude_masks(model: nn.Module, sparsity: float) -> dict[str, torch.Tensor]:
    """Per layer, the `sparsity` fraction of weights with the smallest magnitude masked (TF-MOT's
    prune_low_magnitude at a constant sparsity, every conv and dense layer)."""
    masks = {}
    for name, layer in weight_layers(model):
        values = layer.weight.detach().abs().flatten()
        keep = values.numel() - int(round(sparsity * values.numel()))
        mask = torch.zeros_like(values)
        mask[values.topk(keep).indices] = 1.0
        masks[name] = mask.view_as(layer.weight)
    return masks


def add_masks(model: nn.Module, masks: dict[str, torch.Tensor]) -> None:
    for name, layer in weight_layers(model):
        parametrize.register_parametrization(layer, "weight", Mask(masks[name]))


@torch.no_grad()
def add_clusters(model: nn.Module, clusters: int, iterations: int, keep_zeros: bool = False) -> None:
    """Each layer's weights replaced by `clusters` trainable shared values. With `keep_zeros` the
    zero weights stay a cluster of their own at exactly zero (sparsity-preserving clustering) and
    the others share `clusters - 1` values."""
    for _, layer in weight_layers(model):
        weight = layer.weight.detach()
        zeros = (weight == 0) if keep_zeros else None
        values = weight.flatten()
        live = values[~zeros.flatten()] if zeros is not None else values
        count = clusters - 1 if keep_zeros else clusters
        centroids, live_index = kmeans(live, count, iterations)
        index = torch.zeros(values.numel(), dtype=torch.long)
        index[~zeros.flatten() if zeros is not None else slice(None)] = live_index
        parametrize.register_parametrization(layer, "weight", Clusters(centroids, index, zeros),
                                             unsafe=True)


def add_fake_quant(model: nn.Module) -> list:
    """Fake-quantize every conv/linear weight and the activations LiteRT keeps in int8; returns the
    hook handles and observers (`remove_hooks` takes them off)."""
    for _, layer in weight_layers(model):
        parametrize.register_parametrization(layer, "weight", FakeQuantWeight())
    handles, observers = [], []
    first = ActivationQuant()
    handles.append(model.register_forward_pre_hook(first.input_hook))
    observers.append(first)
    for module in _activation_outputs(model):
        observer = ActivationQuant()
        handles.append(module.register_forward_hook(observer.output_hook))
        observers.append(observer)
    return [handles, observers]


def _activation_outputs(model: nn.Module) -> list[nn.Module]:
    """The modules whose outputs LiteRT quantizes: each ReLU (fused into the layer before it) and
    each conv/linear layer not followed by one (the output layer)."""
    kinds = (nn.Conv2d, nn.Linear, nn.ReLU, nn.ReLU6)
    leaves = [m for m in model.modules() if isinstance(m, kinds)]     # in registration (= call) order
    chosen = []
    for i, module in enumerate(leaves):
        after = leaves[i + 1] if i + 1 < len(leaves) else None
        if isinstance(module, (nn.ReLU, nn.ReLU6)) or (
                isinstance(module, (nn.Conv2d, nn.Linear)) and not isinstance(after, (nn.ReLU, nn.ReLU6))):
            chosen.append(module)
    return chosen


def calibrate(model: nn.Module, quant: list, batches) -> None:
    """Observe the activation ranges on training frames before fine-tuning."""
    _, observers = quant
    for observer in observers:
        observer.calibrating = True
    with torch.no_grad():
        model.eval()
        for batch in batches:
            model(batch)
    for observer in observers:
        observer.calibrating = False


def remove_hooks(quant: list) -> None:
    for handle in quant[0]:
        handle.remove()


@torch.no_grad()
def bake(model: nn.Module) -> nn.Module:
    """Write each constrained weight in (masked, clustered, on the int8 grid) and drop the
    parametrizations: a plain network to export."""
    for _, layer in weight_layers(model):
        if parametrize.is_parametrized(layer, "weight"):
            parametrize.remove_parametrizations(layer, "weight", leave_parametrized=True)
    return model.eval()


def weight_figures(model: nn.Module) -> dict:
    """Per layer: the fraction of weights that are zero, the number of distinct values, and the
    most distinct values in one output channel (what per-channel int8 keeps of clusters)."""
    layers = {name: layer.weight.detach() for name, layer in weight_layers(model)}
    total = sum(w.numel() for w in layers.values())
    zeros = {name: int((w == 0).sum()) for name, w in layers.items()}
    return {"sparsity": sum(zeros.values()) / total,
            "layer_sparsity": {name: zeros[name] / w.numel() for name, w in layers.items()},
            "distinct_weights": {name: int(w.unique().numel()) for name, w in layers.items()},
            "channel_distinct_weights": {name: max(int(c.unique().numel()) for c in w.flatten(1))
                                         for name, w in layers.items()}}


def magnitude_pruning(config: MagnitudePruning, source: StrategySource) -> tuple[nn.Module, dict]:
    """The `magnitude_pruning` preparation's shape (pilotlab.strategies.configs.prepare): the input batch-norm
    folded in, each layer's smallest weights masked. The masks stay on (parametrizations), so that a later
    step (QAT) keeps the zeros too; the prepare job fine-tunes it (pilotlab.strategies.prepared)."""
    model = fold(source.load_model())
    add_masks(model, magnitude_masks(model, config.sparsity))
    return model, {}
