"""The `train` job kind on frames jobs' outputs: checkpoint, result, and drive-time preprocessing."""
import importlib
import json

import numpy as np
import pytest
import torch

from matrix.kinds import KINDS
from matrix.store import outputs_hash
from pilotlab.data.frames import FrameSet
from pilotlab.data.preprocess import DrivePreprocessor
from pilotlab.errors import PilotlabError
from pilotlab.specs import KIND_MODULES
from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
from pilotlab.jobs import train as train_job  # noqa: F401  (registers "train")
from pilotlab.models import load_checkpoint
from tests.pilotlab.data.bagfiles import RawBag
from tests.pilotlab.jobs.context import context, finished
from tests.pilotlab.synthetic import stripe_images


def recording(tmp_path, name, seed, n=24):
    """A bag of 132×200 camera images whose lower half shows the stripe, and the frames job on it."""
    lower, labels = stripe_images(n, seed=seed)
    cameras = np.concatenate([np.full_like(lower, 90), lower], axis=1)
    with RawBag(tmp_path / f"{name}.bag", "ros1") as bag:
        for i, (camera, (v, w)) in enumerate(zip(cameras, labels)):
            bag.twist(10**9 + i * 10**8, float(v), float(w))
            bag.image(10**9 + i * 10**8, camera)
    ctx = context(tmp_path, "frames", name, inputs={"bag": tmp_path / f"{name}.bag"})
    return finished(ctx, KINDS.get("frames").handler(ctx)), cameras


@pytest.fixture(scope="module")
def frames_deps(tmp_path_factory):
    torch.set_num_threads(1)
    folder = tmp_path_factory.mktemp("recordings")
    return [recording(folder, f"run{i}", seed=i) for i in range(4)]


def test_train_job_writes_a_checkpoint_the_brain_can_drive_with(tmp_path, frames_deps):
    deps = {"frames": tuple(dep for dep, _ in frames_deps)}
    progress = []
    ctx = context(tmp_path, "train", "train-pilotnet",
                  {"epochs": 6, "batch_size": 8, "val_fraction": 0.25, "patience": None, "augment": {"flip": True}},
                  deps=deps, progress=lambda **kw: progress.append(kw))
    result = KINDS.get("train").handler(ctx)
    json.dumps(result)
    print({k: result[k] for k in ("val_mse", "val_mse_mean_predictor", "epochs_run", "params")})
    assert result["val_mse"] < 0.5 * result["val_mse_mean_predictor"]
    assert result["params"] == 1_595_528 and result["epochs_run"] == 6 and result["val_by"] == "recording"
    assert result["train_frames"] == 72 and result["val_frames"] == 24 and len(result["val_recordings"]) == 1
    # outside test: a training on 1 frame, with no validation, was "ok" without a word
    assert result["warnings"] == [
        "trained on 72 frame(s): too few to learn to drive from (under 200); record more, or longer laps",
        "validated on 24 frame(s) (under 50): the best epoch and early stopping rest on them; record more, or hold "
        "out another recording (val_by)"]
    assert progress[-1]["completed"] == progress[-1]["total"] == 6 and "loss" in progress[-1]["description"]
    history = json.loads((ctx.out / "history.json").read_text())
    assert [r["epoch"] for r in history] == list(range(1, 7))

    model, checkpoint = load_checkpoint(ctx.out / "model.pt")
    assert checkpoint["arch"] == "pilotnet" and checkpoint["labels"] == result["labels"]
    assert checkpoint["preprocess"] == {"version": 1, "crop_top": 0.5, "crop_bottom": 1.0, "width": 200,
                                        "height": 66, "interpolation": "fast_area", "frames": 1,
                                        "frame_interval_s": pytest.approx(0.1, abs=0.01)}
    brain = DrivePreprocessor.from_checkpoint(checkpoint)
    (val_run,) = result["val_recordings"]
    dep, cameras = frames_deps[val_run]
    saved = FrameSet.load(dep.artifacts)
    with torch.no_grad():
        # the same input, bit for bit; the outputs to float rounding (the drive-time tensor's strides are
        # channels-last, the training batch's NCHW: the convolutions sum in another order)
        assert torch.equal(brain(cameras[5]), saved.inputs(np.array([5])))
        assert torch.allclose(model(brain(cameras[5])), model(saved.inputs(np.array([5]))), rtol=1e-5, atol=1e-6)
        v, w = brain.commands(model(brain(cameras[5])))
    assert abs(w - saved.labels[5, 1]) < 0.5


def test_stacked_model_with_block_split_and_stated_ranges(tmp_path, frames_deps):
    deps = {"frames": tuple(dep for dep, _ in frames_deps[:2])}
    ranges = {"v": [0.0, 5.0], "w": [-2.0, 2.0]}
    ctx = context(tmp_path, "train", "train-stacked",
                  {"arch": "pilotnet_stacked", "options": {"frames": 2}, "epochs": 1, "batch_size": 16,
                   "val_fraction": 0.25, "val_by": "block", "labels": ranges}, deps=deps)
    result = KINDS.get("train").handler(ctx)
    assert result["frames"] == 2 and result["val_by"] == "block" and result["labels"] == ranges
    assert result["val_frames"] == 12 and result["train_frames"] == 36
    _, checkpoint = load_checkpoint(ctx.out / "model.pt")
    assert checkpoint["preprocess"]["frames"] == 2 and checkpoint["config"]["frames"] == 2


def test_train_job_params_are_checked(tmp_path, frames_deps):
    deps = {"frames": (frames_deps[0][0],)}
    with pytest.raises(PilotlabError, match="unknown param 'epoch' .did you mean 'epochs'..; known: arch, augment"):
        KINDS.get("train").handler(context(tmp_path, "train", "t1", {"epoch": 3}, deps=deps))
    with pytest.raises(PilotlabError, match=r"labels: v: \[1.0, 1.0\] is not a range \[lo, hi\] .* with lo < hi"):
        KINDS.get("train").handler(context(tmp_path, "train", "t2", {"labels": {"v": [1, 1], "w": [-1, 1]}}, deps=deps))


def test_a_diverging_training_names_the_recipe_key_to_change(tmp_path, frames_deps):
    """Outside test: "lower the learning rate (lr 100)" left the user to find which one."""
    ctx = context(tmp_path, "train", "train small", {"epochs": 1, "batch_size": 8, "lr": 100, "val_fraction": 0.25},
                  deps={"frames": tuple(dep for dep, _ in frames_deps)})
    with pytest.raises(PilotlabError, match=r"training diverged: .*lower the learning rate \(lr 100\) and run again "
                                            r"\(models.small.lr in the recipe\)$"):
        KINDS.get("train").handler(ctx)


def test_training_runs_alone_on_every_core(tmp_path, frames_deps):
    from pilotlab.hardware import cpu_count
    assert KINDS.get("train").runs_alone({})
    torch.set_num_threads(1)            # as a worker sharing the cores with another would start
    ctx = context(tmp_path, "train", "train-threads", {"epochs": 1, "batch_size": 8, "val_fraction": 0.25},
                  deps={"frames": tuple(dep for dep, _ in frames_deps)})
    KINDS.get("train").handler(ctx)
    assert torch.get_num_threads() == cpu_count()
    torch.set_num_threads(1)


def test_the_same_training_writes_the_same_checkpoint_bytes(tmp_path, frames_deps):
    """The checkpoint holds what the inputs determine, not the wall times (they stay in result.json and
    history.json): two runs of one training give one file, so its compressed size is the same too (the
    slow Dask and parallel pipeline tests compare it: it had differed by 10 bytes)."""
    deps = {"frames": tuple(dep for dep, _ in frames_deps[:2])}
    params = {"epochs": 2, "batch_size": 16, "val_fraction": 0.25}
    for module in KIND_MODULES:   # every kind, then the measured keys declared beside the guesses
        importlib.import_module(module)
    outs, histories, tokens = [], [], []
    for run in ("a", "b"):
        ctx = context(tmp_path / run, "train", "train-twice", params, deps=deps)
        result = KINDS.get("train").handler(ctx)
        assert result["seconds"] > 0 and len(result["epoch_seconds"]) == 2 and all(s > 0 for s in result["epoch_seconds"])
        outs.append((ctx.out / "model.pt").read_bytes())
        histories.append((ctx.out / "history.json").read_bytes())
        tokens.append(outputs_hash({"status": "ok", "value": result}, KINDS.get("train").measured))
    # outside test: `--force train` reran all that stood on a byte-identical network (history.json held the times)
    assert outs[0] == outs[1] and histories[0] == histories[1] and tokens[0] == tokens[1]
    _, checkpoint = load_checkpoint(ctx.out / "model.pt")
    assert "seconds" not in checkpoint["result"] and all("seconds" not in row for row in checkpoint["history"])
