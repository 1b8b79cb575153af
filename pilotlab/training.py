"""The training loop shared by the `train` job and by strategies that fine-tune (pruning, QAT).

`fit` trains a model in place with Adam on the MSE of normalised labels and returns the history, one
dict per epoch. It augments batches as `FitConfig.augment` says, stops early when the validation loss
has not improved for `patience` epochs (restoring the best weights), and reports progress through
callbacks, so the engine (or `FitProgress`, a rich bar) can show it.

`precision` "bf16" trains in mixed precision: the forward pass runs under torch.autocast (convolutions
and matrix products in bfloat16), while the weights, their gradients, Adam's state and the loss stay
float32, and validation is float32. Where the CPU computes bf16 natively (AVX512-BF16, AMX) a PilotNet
step takes 0.4× the time (tests/pilotlab/test_training_benchmark.py); elsewhere torch emulates bf16,
slower than fp32, so "auto" (the train job's default) is bf16 only there. Every history row says
which precision trained it.
"""
from __future__ import annotations

import copy
import math
import time
import typing
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, fields

import numpy as np
import torch
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from torch import nn

from pilotlab.cpuinfo import native_cpu_dtype
from pilotlab.data.augment import AugmentConfig, augment_batch, epoch_order
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.errors import PilotlabError
from pilotlab.specs.train import Precision

PRECISIONS = typing.get_args(Precision)


class Diverged(PilotlabError):
    """The loss became NaN or infinite while training: a learning rate too high, most often."""


@dataclass(frozen=True)
class FitConfig:
    """How one fit runs. The train job's settings and their defaults are pilotlab.specs.train.TrainSpec;
    here only what a caller (a strategy's fine-tuning) need not say has a neutral value."""
    epochs: int
    batch_size: int
    lr: float
    seed: int = 0
    frames: int = 1                  # consecutive frames per input (temporal models)
    patience: int | None = None      # early stopping on validation loss (None: never stop early)
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    precision: Precision = "fp32"    # fp32, bf16 (mixed) or auto (see the module docstring)

    def as_dict(self) -> dict:
        return {**{f.name: getattr(self, f.name) for f in fields(self)}, "augment": self.augment.as_dict()}


EpochCallback = Callable[[dict], None]
BatchCallback = Callable[[int, int, int, float], None]   # (epoch, batch, batches, loss)


def fit_precision(requested: str) -> str:
    """The precision a fit trains in: "auto" is "bf16" where this CPU computes bf16 natively, else "fp32"."""
    if requested not in PRECISIONS:
        raise PilotlabError(f"precision {requested!r} is not one of {', '.join(PRECISIONS)}")
    if requested == "auto":
        return "bf16" if native_cpu_dtype("bfloat16") else "fp32"
    return requested


def evaluate(model: nn.Module, data: FrameSet, ranges: LabelRanges, *, frames: int = 1,
             batch_size: int = 256) -> dict[str, float]:
    """MSE on normalised labels: over both outputs ("mse"), and of v and w alone."""
    model.eval()
    targets = torch.from_numpy(ranges.normalise(np.asarray(data.labels)))
    squared = torch.zeros(2, dtype=torch.float64)
    with torch.no_grad():
        for inputs, index in data.batches(batch_size, frames=frames):
            squared += ((model(inputs) - targets[index]) ** 2).sum(0).double()
    mse_v, mse_w = (squared / max(len(data), 1)).tolist()
    return {"mse": (mse_v + mse_w) / 2, "mse_v": mse_v, "mse_w": mse_w}


def evaluate_mse(model: nn.Module, data: FrameSet, ranges: LabelRanges, *, frames: int = 1,
                 batch_size: int = 256) -> float:
    """Mean squared error on normalised labels."""
    return evaluate(model, data, ranges, frames=frames, batch_size=batch_size)["mse"]


def mean_predictor_mse(train: FrameSet, val: FrameSet, ranges: LabelRanges) -> dict[str, float]:
    """MSE on `val` of always predicting the mean training label (the bar a network must beat)."""
    mean = ranges.normalise(np.asarray(train.labels)).mean(0)
    per_output = ((ranges.normalise(np.asarray(val.labels)) - mean) ** 2).mean(0).astype(float)
    return {"mse": float(per_output.mean()), "mse_v": float(per_output[0]), "mse_w": float(per_output[1])}


class _Epochs:
    """One model's training state: runs an epoch over a given order of frames."""

    def __init__(self, model: nn.Module, train: FrameSet, ranges: LabelRanges, config: FitConfig,
                 precision: str = "fp32"):
        if not any(p.requires_grad for p in model.parameters()):
            raise PilotlabError(f"the network ({type(model).__name__}) has no trainable parameters, so there is "
                                "nothing to train; give it layers with weights, or use it as it is (train: false)")
        self.model, self.train, self.config = model, train, config
        self.bf16 = precision == "bf16"
        self.optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
        self.generator = torch.Generator().manual_seed(config.seed)
        self.labels = torch.from_numpy(np.asarray(train.labels, np.float32).copy())   # physical
        self.lo = torch.tensor([ranges.v[0], ranges.w[0]], dtype=torch.float32)
        self.span = torch.tensor([ranges.v[1], ranges.w[1]], dtype=torch.float32) - self.lo

    def run(self, epoch: int, order: np.ndarray, on_batch: BatchCallback | None) -> float:
        """Mean training loss of the epoch."""
        self.model.train()
        size, losses = self.config.batch_size, []
        batches = max(1, -(-len(order) // size))
        for b, start in enumerate(range(0, len(order), size)):
            losses.append(self._step(order[start:start + size]))
            if not math.isfinite(losses[-1]) and epoch == 1 and b == 0:   # before any step: not the training's doing
                raise PilotlabError(f"the network's output gives a loss of {losses[-1]} on the first batch, before "
                                    "any training step: check its forward pass and initialisation (a NaN or "
                                    "infinity in its output)")
            if not math.isfinite(losses[-1]):
                raise Diverged(f"training diverged: the loss is {losses[-1]} at epoch {epoch}, batch {b + 1} "
                                    f"of {batches}; lower the learning rate (lr {self.config.lr:g}) and run again")
            if on_batch:
                on_batch(epoch, b + 1, batches, losses[-1])
        return float(np.mean(losses))

    def _step(self, index: np.ndarray) -> float:
        inputs, labels = augment_batch(self.train.inputs(index, self.config.frames), self.labels[index],
                                       self.config.augment, self.generator)
        self.optimizer.zero_grad()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=self.bf16):
            outputs = self.model(inputs)
        loss = nn.functional.mse_loss(outputs.float(), (labels - self.lo) / self.span)
        loss.backward()
        self.optimizer.step()
        return loss.item()


class _Best:
    """The epoch with the lowest validation loss so far, and its weights."""

    def __init__(self):
        self.loss, self.state, self.row, self.stale = float("inf"), None, None, 0

    def update(self, model: nn.Module, row: dict) -> None:
        if row["val_loss"] < self.loss:
            self.loss, self.state, self.row, self.stale = row["val_loss"], copy.deepcopy(model.state_dict()), row, 0
        else:
            self.stale += 1

    def restore(self, model: nn.Module) -> None:
        if self.state is not None:
            model.load_state_dict(self.state)
            self.row["best"] = True


def fit(model: nn.Module, train: FrameSet, ranges: LabelRanges, config: FitConfig,
        val: FrameSet | None = None, on_epoch: EpochCallback | None = None,
        on_batch: BatchCallback | None = None) -> list[dict]:
    """Train `model` in place; returns the history. With `val`, the weights of the epoch with the
    lowest validation loss are restored at the end (that row has "best": True), and with `patience`
    training stops once that many epochs in a row did not improve on it."""
    train.check_finite("training data")
    if val is not None:
        val.check_finite("validation data")
    torch.manual_seed(config.seed)
    sample = train.inputs(np.arange(min(2, len(train))), config.frames)
    precision = fit_precision(config.precision)
    if precision == "bf16" and config.precision == "auto" and not _runs(model, sample, bf16=True):
        precision = "fp32"   # a network of the user's that autocast breaks (a dtype it mixes itself)
    with _channels_last_convolutions(model, sample):
        history = _fit_epochs(model, train, ranges, config, precision, val, on_epoch, on_batch)
    model.eval()
    return history


@contextmanager
def _channels_last_convolutions(model: nn.Module, sample: torch.Tensor) -> Iterator[None]:
    """The 2-D convolutions' weights channels-last (NHWC) while fitting, the input NCHW: torch then runs
    those convolutions channels-last, ~1.6× faster a training step on 2 threads (PilotNet, a batch of
    64, torch 2.13: tests/pilotlab/test_training_benchmark.py), while the input's BatchNorm stays on
    the NCHW layout it is fast on. Their outputs are channels-last too, which a network of the user's
    may not take (`x.view(n, -1)` after a convolution cannot view them): one forward pass of `sample`
    (eval mode, no gradient: nothing learns) tries it first, and the model trains in its own layout
    if that fails. The weights go back to the standard layout afterwards, for export and quantization."""
    tensors = [t for conv in model.modules() if isinstance(conv, nn.Conv2d)
               for t in (*conv.parameters(), *conv.buffers()) if t.dim() == 4]   # pruning's masks, too
    try:
        _set_layout(tensors, torch.channels_last)
        if tensors and not _runs(model, sample):
            _set_layout(tensors, torch.contiguous_format)
        yield
    finally:
        _set_layout(tensors, torch.contiguous_format)


def _set_layout(tensors: list[torch.Tensor], layout: torch.memory_format) -> None:
    for tensor in tensors:
        tensor.data = tensor.data.contiguous(memory_format=layout)   # the same Parameter: the optimizer keeps it


def _runs(model: nn.Module, sample: torch.Tensor, bf16: bool = False) -> bool:
    """Whether one forward pass of `sample` goes through (eval mode, no gradient: nothing learns); with
    `bf16`, under autocast and to a finite output."""
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            output = model(sample)
        return not bf16 or bool(torch.isfinite(output.float()).all())
    except Exception:   # any error: the layout (or autocast) does not suit this network (fit says what fails)
        return False
    finally:
        model.train(was_training)


def _fit_epochs(model: nn.Module, train: FrameSet, ranges: LabelRanges, config: FitConfig, precision: str,
                val: FrameSet | None, on_epoch: EpochCallback | None, on_batch: BatchCallback | None) -> list[dict]:
    epochs, best, history = _Epochs(model, train, ranges, config, precision), _Best(), []
    w_limit = max(abs(ranges.w[0]), abs(ranges.w[1]))
    for epoch in range(1, config.epochs + 1):
        started = time.perf_counter()
        order = epoch_order(np.asarray(train.labels)[:, 1], w_limit, config.augment,
                            np.random.default_rng(config.seed + epoch))
        row = {"epoch": epoch, "train_loss": epochs.run(epoch, order, on_batch), "precision": precision}
        if val is not None and len(val):
            scores = evaluate(model, val, ranges, frames=config.frames)
            if not math.isfinite(scores["mse"]):
                raise Diverged(f"training diverged: the validation loss is {scores['mse']} after epoch {epoch}; "
                                    f"lower the learning rate (lr {config.lr:g}) and run again")
            row.update(val_loss=scores["mse"], val_mse_v=scores["mse_v"], val_mse_w=scores["mse_w"])
            best.update(model, row)
        row["seconds"] = round(time.perf_counter() - started, 3)
        history.append(row)
        if on_epoch:
            on_epoch(row)
        if config.patience is not None and best.stale >= config.patience:
            break
    best.restore(model)
    return history


class FitProgress:
    """A rich progress bar for `fit` outside the engine:

        with FitProgress(config.epochs) as bar:
            fit(model, train, ranges, config, val, on_epoch=bar.on_epoch, on_batch=bar.on_batch)
    """

    def __init__(self, epochs: int, description: str = "training"):
        self.epochs, self.description = epochs, description
        self.bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                            TextColumn("{task.fields[loss]}"), TimeRemainingColumn())
        self.task = self.bar.add_task(description, total=epochs, loss="")
        self.last = ""

    def __enter__(self) -> FitProgress:
        self.bar.start()
        return self

    def __exit__(self, *exc) -> None:
        self.bar.stop()

    def on_batch(self, epoch: int, batch: int, batches: int, loss: float) -> None:
        self.bar.update(self.task, completed=epoch - 1 + batch / batches,
                        description=f"{self.description} epoch {epoch}/{self.epochs}",
                        loss=f"loss {loss:.4f}{self.last}")

    def on_epoch(self, row: dict) -> None:
        self.last = f"  val {row['val_loss']:.4f}" if "val_loss" in row else ""
        self.bar.update(self.task, completed=row["epoch"], loss=f"loss {row['train_loss']:.4f}{self.last}")
