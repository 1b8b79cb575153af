"""The training loop shared by the `train` job and by strategies that fine-tune (pruning, QAT).

`fit` trains a model in place with Adam on the MSE of normalised labels and returns the history.
(First version: the datasets/training issue extends it with augmentation, early stopping and
progress; the signature stays.)
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from pilotlab.data.frames import FrameSet, LabelRanges


@dataclass(frozen=True)
class FitConfig:
    epochs: int = 10
    batch_size: int = 64
    lr: float = 1e-3
    seed: int = 0
    frames: int = 1                  # consecutive frames per input (temporal models)
    patience: int | None = None      # early stopping on validation loss (None: never stop early)


EpochCallback = Callable[[dict], None]


def evaluate_mse(model: nn.Module, data: FrameSet, ranges: LabelRanges, *, frames: int = 1,
                 batch_size: int = 256) -> float:
    """Mean squared error on normalised labels."""
    model.eval()
    targets = ranges.normalise(np.asarray(data.labels))
    total = 0.0
    with torch.no_grad():
        for inputs, index in data.batches(batch_size, frames=frames):
            total += float(((model(inputs) - torch.from_numpy(targets[index])) ** 2).sum())
    return total / (2 * len(data))


def fit(model: nn.Module, train: FrameSet, ranges: LabelRanges, config: FitConfig,
        val: FrameSet | None = None, on_epoch: EpochCallback | None = None) -> list[dict]:
    torch.manual_seed(config.seed)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    targets = torch.from_numpy(ranges.normalise(np.asarray(train.labels)))
    history: list[dict] = []
    for epoch in range(config.epochs):
        model.train()
        losses = []
        for inputs, index in train.batches(config.batch_size, frames=config.frames,
                                           shuffle=True, seed=config.seed + epoch):
            optimizer.zero_grad()
            loss = nn.functional.mse_loss(model(inputs), targets[index])
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
        row = {"epoch": epoch + 1, "train_loss": float(np.mean(losses))}
        if val is not None and len(val):
            row["val_loss"] = evaluate_mse(model, val, ranges, frames=config.frames)
        history.append(row)
        if on_epoch:
            on_epoch(row)
    model.eval()
    return history
