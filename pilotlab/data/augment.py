"""Training-time augmentation on whole batches (torch, vectorised), selectable in the recipe.

    augment: {flip: true, oversample_curves: 2, color_jitter: 0.2, blur: 0.3, affine: 0.3}

- flip: half the images mirrored left-right, with w negated (as DeepLearningStudio's flip_images);
- oversample_curves: the extra weight of curve frames (DeepLearningStudio's add_extreme_data): each
  frame whose |w| exceeds `curve_threshold` × the largest |w| of the label ranges appears
  1 + oversample_curves times per epoch on average (2.5: two or three extra copies, half each);
- color_jitter: brightness, contrast and saturation each scaled by a factor in [1 - s, 1 + s];
- blur: the probability of a Gaussian blur (5×5, sigma in [0.1, 2]), as DLS's GaussianBlur(5, (0.1, 2));
- affine: the probability of a small rotation (±3°), shift (±4 %) and zoom (±5 %).
A stack of frames (temporal models) gets the same transform on each of its frames.
"""
from __future__ import annotations

import math

import numpy as np
import torch
from torch.nn import functional as F

from pilotlab.specs.train import AugmentConfig  # the settings live with the train job's


def epoch_order(labels_w: np.ndarray, w_limit: float, config: AugmentConfig, rng: np.random.Generator) -> np.ndarray:
    """A shuffled index over the frames, curves repeated `oversample_curves` extra times."""
    index = np.arange(len(labels_w))
    if config.oversample_curves:
        curves = index[np.abs(labels_w) > config.curve_threshold * w_limit]
        whole, part = divmod(config.oversample_curves, 1.0)
        extra = [curves] * int(whole) + [curves[rng.random(len(curves)) < part]]
        index = np.concatenate([index, *extra])
    return rng.permutation(index)


def augment_batch(images: torch.Tensor, labels: torch.Tensor, config: AugmentConfig,
                  generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """images float [B, 3F, H, W] in [0, 1], labels physical [B, 2] -> augmented copies."""
    if not config.transforms_images:
        return images, labels
    images, labels = images.clone(), labels.clone()
    if config.flip:
        mask = torch.rand(len(images), generator=generator) < 0.5
        images[mask] = images[mask].flip(-1)
        labels[mask, 1] = -labels[mask, 1]
    if config.color_jitter:
        images = color_jitter(images, config.color_jitter, generator)
    if config.blur:
        images = _on_some(images, config.blur, generator, gaussian_blur)
    if config.affine:
        images = _on_some(images, config.affine, generator, small_affine)
    return images, labels


def _uniform(n: int, lo: float, hi: float, generator: torch.Generator) -> torch.Tensor:
    return lo + (hi - lo) * torch.rand(n, generator=generator)


def _on_some(images: torch.Tensor, probability: float, generator: torch.Generator, transform) -> torch.Tensor:
    chosen = torch.nonzero(torch.rand(len(images), generator=generator) < probability).flatten()
    if len(chosen):
        images[chosen] = transform(images[chosen], generator)
    return images


def color_jitter(images: torch.Tensor, strength: float, generator: torch.Generator) -> torch.Tensor:
    n, channels, height, width = images.shape
    x = images.reshape(n, channels // 3, 3, height, width)
    factors = [_uniform(n, 1 - strength, 1 + strength, generator).view(n, 1, 1, 1, 1) for _ in range(3)]
    brightness, contrast, saturation = factors
    x = x * brightness
    gray = (0.299 * x[:, :, :1] + 0.587 * x[:, :, 1:2] + 0.114 * x[:, :, 2:3])
    x = (x - gray.mean(dim=(-2, -1), keepdim=True)) * contrast + gray.mean(dim=(-2, -1), keepdim=True)
    gray = (0.299 * x[:, :, :1] + 0.587 * x[:, :, 1:2] + 0.114 * x[:, :, 2:3])
    x = gray + (x - gray) * saturation
    return x.clamp_(0.0, 1.0).reshape(n, channels, height, width)


def gaussian_blur(images: torch.Tensor, generator: torch.Generator, size: int = 5) -> torch.Tensor:
    """Each image blurred with its own sigma (one depthwise convolution for the whole batch)."""
    n, channels, height, width = images.shape
    sigma = _uniform(n, 0.1, 2.0, generator).view(n, 1)
    offsets = torch.arange(size, dtype=images.dtype) - size // 2
    kernel = torch.exp(-(offsets.view(1, -1) ** 2) / (2 * sigma ** 2))
    kernel = kernel / kernel.sum(dim=1, keepdim=True)                           # [n, size]
    kernel = kernel.repeat_interleave(channels, dim=0)                           # [n·C, size]
    x = F.pad(images.reshape(1, n * channels, height, width), [size // 2] * 4, mode="replicate")
    x = F.conv2d(x, kernel.view(-1, 1, 1, size), groups=n * channels)           # along rows
    x = F.conv2d(x, kernel.view(-1, 1, size, 1), groups=n * channels)           # along columns
    return x.reshape(n, channels, height, width)


def small_affine(images: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    n = len(images)
    angle = _uniform(n, -3.0, 3.0, generator) * math.pi / 180
    scale = _uniform(n, 0.95, 1.05, generator)
    shift = torch.stack([_uniform(n, -0.08, 0.08, generator), _uniform(n, -0.08, 0.08, generator)], 1)
    cos, sin = torch.cos(angle) / scale, torch.sin(angle) / scale
    theta = torch.stack([torch.stack([cos, -sin, shift[:, 0]], 1), torch.stack([sin, cos, shift[:, 1]], 1)], 1)
    grid = F.affine_grid(theta.to(images.dtype), list(images.shape), align_corners=False)
    return F.grid_sample(images, grid, mode="bilinear", padding_mode="border", align_corners=False)
