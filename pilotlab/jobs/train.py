"""The `train` job's handler: frames from one or more recordings -> a trained network checkpoint.

deps: "frames", a group of `frames` jobs (one recording each).
params: pilotlab.specs.train.TrainSpec (arch and its options, or the user's network / TorchScript /
ONNX file and weights (their content: the job's inputs, pilotlab.models.user), epochs, batch size, lr, early
stopping, the validation split, augmentation, label ranges, seed).

artifacts: model.pt (pilotlab.models.save_checkpoint: arch, config, state_dict, labels, preprocess
with "frames", history, training params and split), history.json.
result: val_mse, val_mse_v, val_mse_w (normalised labels, best epoch), val_mse_mean_predictor
(+ _v, _w: predicting the mean training label on the same validation frames), train_loss, epochs_run,
best_epoch, stopped_early, params, train_frames, val_frames, warnings (too little data: data_warnings),
recordings, val_recordings, val_by,
labels, frames, seconds, checkpoint, source (where the model came from: arch, or the user's file and
its sha256), trained (false: the user's weights or file as they are; then no train_loss). Without validation frames the val_* entries are absent.
"""
from __future__ import annotations

import json
import time
from typing import Any

import numpy as np
import torch

from matrix.kinds import JobContext
from matrix.runs import cores, worker_share
from matrix.store import without_keys
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.data.split import Split, split_validation
from pilotlab.errors import PilotlabError
from pilotlab.models import build_model, input_frames, make_config, save_checkpoint
from pilotlab.specs.train import TrainSpec
from pilotlab.training import Diverged, FitConfig, evaluate, fit, mean_predictor_mse


def load_frames(ctx: JobContext) -> tuple[FrameSet, dict[str, Any]]:
    """All recordings as one FrameSet, and the preprocessing they share."""
    sets = [FrameSet.load(dep.artifacts) for dep in ctx.dep_group("frames")]
    settings_seen = {json.dumps(s.meta.get("preprocess"), sort_keys=True) for s in sets}
    if len(settings_seen) != 1:
        raise PilotlabError(f"{ctx.name}: its frames jobs were preprocessed differently "
                            f"({'; '.join(sorted(settings_seen))}); give them the same crop and size")
    preprocess = {**(sets[0].meta.get("preprocess") or {}), "frame_interval_s": frame_interval(sets)}
    return FrameSet.concat(sets), preprocess


def frame_interval(sets: list[FrameSet]) -> float | None:
    """The median spacing of consecutive frames in simulated seconds (temporal brains stack frames
    this far apart at drive time)."""
    gaps = [(s.meta["end_ns"] - s.meta["start_ns"]) / 1e9 / (len(s) - 1) for s in sets
            if len(s) > 1 and "end_ns" in s.meta and "start_ns" in s.meta]
    return round(float(np.median(gaps)), 6) if gaps else None


def label_ranges(spec: Any, data: FrameSet) -> LabelRanges:
    if spec == "auto":
        return LabelRanges.covering(np.asarray(data.labels))
    try:
        ranges = LabelRanges.from_dict(spec)
        spans = [float(hi) - float(lo) for lo, hi in (ranges.v, ranges.w)]
    except (KeyError, TypeError, ValueError):
        raise PilotlabError(f"labels = {spec!r}: give \"auto\" or {{\"v\": [lo, hi], \"w\": [lo, hi]}}") from None
    if min(spans) <= 0:
        raise PilotlabError(f"labels = {spec!r}: each range needs lo < hi")
    return ranges


def progress_callbacks(ctx: JobContext, epochs: int):
    def on_batch(epoch: int, batch: int, batches: int, loss: float) -> None:
        ctx.progress(epoch - 1 + batch / batches, epochs, f"epoch {epoch}/{epochs} loss {loss:.4f}")

    def on_epoch(row: dict) -> None:
        shown = (f"{k} {v:.5g}" if isinstance(v, float) else f"{k} {v}"   # "precision bf16"
                 for k, v in row.items() if k not in ("epoch", "best"))
        ctx.log.info("epoch %d: %s", row["epoch"], ", ".join(shown))
    return on_batch, on_epoch


def validation_scores(model, train: FrameSet, val: FrameSet, ranges: LabelRanges, frames: int) -> dict:
    if not len(val):
        return {}
    scores, mean = evaluate(model, val, ranges, frames=frames), mean_predictor_mse(train, val, ranges)
    return {**{f"val_{k}": v for k, v in scores.items()},               # val_mse, val_mse_v, val_mse_w
            **{f"val_{k}_mean_predictor": v for k, v in mean.items()}}


def split_frames(ctx: JobContext, data: FrameSet, p: TrainSpec) -> tuple[FrameSet, FrameSet, Split]:
    split = split_validation(data.recording, p.val_fraction, p.val_by, p.seed)
    if not len(split.train):
        raise PilotlabError(f"{ctx.name}: no frames left to train on after holding out val_fraction = "
                            f"{p.val_fraction} of {len(data)}; lower val_fraction or record more")
    return data.subset(split.train), data.subset(split.val), split


def make_model(ctx: JobContext, p: TrainSpec, preprocess: dict) -> tuple[torch.nn.Module, str, Any, FitConfig, dict]:
    """The model (freshly initialised and seeded, or the user's: from their weights or file), its
    checkpoint arch and config, how to fit it, and where it came from."""
    from pilotlab.models import user
    torch.manual_seed(p.seed)
    where = f"models.{ctx.name.removeprefix('train ')}"
    if p.source == "arch":
        config = make_config(p.arch, p.options)
        model, arch, origin = build_model(p.arch, config), p.arch, {"kind": "arch", "arch": p.arch}
        if p.weights is not None:
            origin.update(user.builtin_weights(model, ctx.inputs["weights"], where))
    else:
        shape = (3, int(preprocess.get("height", 66)), int(preprocess.get("width", 200)))
        model, arch, config, origin = user.user_model(p, dict(ctx.inputs), shape, where)
    fit_config = FitConfig(epochs=p.epochs, batch_size=p.batch_size, lr=p.lr, seed=p.seed,
                           frames=input_frames(config), patience=p.patience, augment=p.augment,
                           precision=p.precision)
    return model, arch, config, fit_config, origin


def summarise(model, history: list[dict], data: FrameSet, train: FrameSet, val: FrameSet, split: Split,
              ranges: LabelRanges, fit_config: FitConfig, seconds: float) -> dict[str, Any]:
    trained = {"train_loss": history[-1]["train_loss"], "epochs_run": len(history),
               "best_epoch": next((r["epoch"] for r in history if r.get("best")), len(history)),
               "stopped_early": len(history) < fit_config.epochs,
               "precision": history[0]["precision"]} if history else {"epochs_run": 0}
    return {**validation_scores(model, train, val, ranges, fit_config.frames), **trained,
            "params": sum(t.numel() for t in model.parameters()), "train_frames": len(train),
            "val_frames": len(val), "recordings": int(len(np.unique(data.recording))),
            "val_recordings": split.val_recordings, "val_by": split.by, "labels": ranges.as_dict(),
            "frames": fit_config.frames, "seconds": round(seconds, 2), "checkpoint": "model.pt"}


MIN_TRAIN_FRAMES = 200   # fewer, and a network learns the frames, not the driving (the quickstart trains on ~750)
MIN_VAL_FRAMES = 50      # fewer, and the best epoch and early stopping rest on noise


def data_warnings(train_frames: int, val_frames: int, trains: bool) -> list[str]:
    """What the report and the log say of a training on too little data (it ran on one frame, "ok")."""
    if not trains:
        return []
    warnings = [f"trained on {train_frames} frame(s): too few to learn to drive from (under {MIN_TRAIN_FRAMES}); "
                "record more, or longer laps"] if train_frames < MIN_TRAIN_FRAMES else []
    if val_frames == 0:
        warnings.append("no validation frames: the last epoch is kept, with no early stopping (val_fraction 0, or "
                        "too few frames to hold any out)")
    elif val_frames < MIN_VAL_FRAMES:
        warnings.append(f"validated on {val_frames} frame(s) (under {MIN_VAL_FRAMES}): the best epoch and early "
                        "stopping rest on them; record more, or hold out another recording (val_by)")
    return warnings


def run_train(ctx: JobContext) -> dict[str, Any]:
    p: TrainSpec = ctx.spec
    # a training runs alone (specs/train.py: trains_alone): every core is its; a model used as it is runs
    # beside other jobs, on its worker's share
    torch.set_num_threads(cores() if p.trains else worker_share())
    data, preprocess = load_frames(ctx)
    train, val, split = split_frames(ctx, data, p)
    ranges = label_ranges(p.labels, data)
    model, arch, config, fit_config, origin = make_model(ctx, p, preprocess)
    on_batch, on_epoch = progress_callbacks(ctx, p.epochs)
    started = time.perf_counter()
    try:
        history = fit(model, train, ranges, fit_config, val=val, on_epoch=on_epoch, on_batch=on_batch) if p.trains \
            else []
    except Diverged as error:   # the setting to change is the recipe's, which the fit does not know
        raise PilotlabError(f"{error} (models.{ctx.name.removeprefix('train ')}.lr in the recipe)") from None
    result = {**summarise(model, history, data, train, val, split, ranges, fit_config, time.perf_counter() - started),
              "source": origin, "trained": p.trains, "epoch_seconds": [row.get("seconds") for row in history]}
    if warnings := data_warnings(len(train), len(val), p.trains):
        result["warnings"] = warnings
        for warning in warnings:
            ctx.log.warning("%s", warning)
    save_checkpoint(ctx.out / "model.pt", model, arch, config, labels=ranges.as_dict(),
                    preprocess={**preprocess, "frames": fit_config.frames}, history=without_wall_times(history),
                    training={**p.as_dict(), "fit": fit_config.as_dict()}, result=without_wall_times(result),
                    source=origin)
    # without the wall times too (they are the result's): the same training writes the same file, so a forced
    # rerun that trained the same network leaves what stands on it fresh (specs/guesses.py: measured keys)
    (ctx.out / "history.json").write_text(json.dumps(without_wall_times(history), indent=1))
    return result


WALL_TIMES = frozenset({"seconds", "epoch_seconds"})


def without_wall_times(value: Any) -> Any:
    """`value` less its wall times: a checkpoint (and history.json) holds what the inputs determine, so the
    same training gives the same bytes (and the same compressed size) on every run; the times stay in
    result.json (seconds, epoch_seconds)."""
    return without_keys(value, WALL_TIMES)
