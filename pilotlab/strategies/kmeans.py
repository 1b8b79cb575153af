"""k-means weight sharing on one weight tensor, for the `cluster` strategy and the TF-MOT clustering
(mot_torch.py)."""
from __future__ import annotations

import torch
from torch import nn


@torch.no_grad()
def kmeans(values: torch.Tensor, clusters: int, iterations: int) -> tuple[torch.Tensor, torch.Tensor]:
    """1-D k-means (linear initialisation between min and max, TF-MOT's default): centroids and
    each value's cluster."""
    centroids = torch.linspace(float(values.min()), float(values.max()), clusters)
    for _ in range(iterations):
        index = nearest(values, centroids)
        sums = torch.zeros(clusters).index_add_(0, index, values)
        counts = torch.zeros(clusters).index_add_(0, index, torch.ones_like(values))
        centroids = torch.where(counts > 0, sums / counts.clamp(min=1), centroids)
    return centroids, nearest(values, centroids)


@torch.no_grad()
def cluster_weights(weight: nn.Parameter, clusters: int, iterations: int) -> torch.Tensor:
    """Replace `weight` by its k-means centroids; returns each weight's cluster index."""
    centroids, index = kmeans(weight.detach().flatten(), clusters, iterations)
    weight.copy_(centroids[index].view_as(weight))
    return index


def nearest(values: torch.Tensor, centroids: torch.Tensor) -> torch.Tensor:
    ordered, order = centroids.sort()
    bounds = (ordered[1:] + ordered[:-1]) / 2        # 1-D: nearest centroid by the midpoints
    return order[torch.bucketize(values, bounds)]


def share_gradients(weight: nn.Parameter, index: torch.Tensor):
    counts = torch.zeros(int(index.max()) + 1).index_add_(0, index, torch.ones(index.numel())).clamp(min=1)

    def mean_per_cluster(grad: torch.Tensor) -> torch.Tensor:
        sums = torch.zeros_like(counts).index_add_(0, index, grad.flatten())
        return (sums / counts)[index].view_as(grad)
    return weight.register_hook(mean_per_cluster)


@torch.no_grad()
def snap_to_centroids(weight: nn.Parameter, index: torch.Tensor) -> None:
    values = weight.detach().flatten()
    sums = torch.zeros(int(index.max()) + 1).index_add_(0, index, values)
    counts = torch.zeros_like(sums).index_add_(0, index, torch.ones_like(values)).clamp(min=1)
    weight.copy_((sums / counts)[index].view_as(weight))
