"""`cluster`: k-means weight sharing, as the study's CQAT (TensorFlow Model Optimization's
clustering): each conv/linear layer's weights take one of `clusters` shared values, and
fine-tuning trains the shared values (every weight of a cluster gets the cluster's mean gradient,
so with Adam the cluster members stay equal).

The saved network is dense fp32 (deployable formats have no codebook type), so it is as large on
disk as the baseline but compresses to ~log2(clusters) bits per weight; the result reports the
number of distinct values per layer (config: configs/cluster.py).
"""
from __future__ import annotations

from pilotlab.strategies.common import finetune, save_float_model, weight_layers
from pilotlab.strategies.configs.cluster import ClusterConfig
from pilotlab.strategies.kmeans import cluster_weights, share_gradients, snap_to_centroids
from pilotlab.strategies.apply import StrategySource


def cluster(config: ClusterConfig, source: StrategySource) -> dict:
    model = source.load_model()
    assignments = {name: cluster_weights(layer.weight, config.clusters, config.iterations)
                   for name, layer in weight_layers(model)}
    handles = [share_gradients(layer.weight, assignments[name]) for name, layer in weight_layers(model)]
    history = finetune(model, source, epochs=config.finetune_epochs, lr=config.lr, batch_size=config.batch_size)
    for handle in handles:
        handle.remove()
    for name, layer in weight_layers(model):
        snap_to_centroids(layer.weight, assignments[name])   # remove float drift, if any
    distinct = {name: int(layer.weight.detach().unique().numel()) for name, layer in weight_layers(model)}
    save_float_model(model, source, config.format, extra={"clusters": config.clusters})
    return {"clusters": config.clusters, "distinct_weights": distinct, "finetune": history}
