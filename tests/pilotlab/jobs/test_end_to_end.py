"""Slow: four 640×480 recordings (two "circuits", both directions) -> frames jobs -> train job."""
import numpy as np
import pytest
import torch

from matrix.kinds import KINDS
from pilotlab.jobs import frames as frames_job  # noqa: F401  (registers "frames")
from pilotlab.jobs import train as train_job  # noqa: F401  (registers "train")
from pilotlab.models import load_checkpoint
from tests.pilotlab.data.bagfiles import RawBag
from tests.pilotlab.jobs.context import context, finished
from tests.pilotlab.synthetic import stripe_images


def record(tmp_path, name, kind, seed, n=80):
    lower, labels = stripe_images(n, height=240, width=640, seed=seed)
    sky = np.zeros_like(lower)
    sky[:] = (150, 180, 220)
    path = tmp_path / (f"{name}.bag" if kind == "ros1" else name)
    with RawBag(path, kind) as bag:
        for i, (image, (v, w)) in enumerate(zip(np.concatenate([sky, lower], axis=1), labels)):
            bag.twist(10**9 + i * 5 * 10**7, float(v), float(w))
            bag.image(10**9 + i * 5 * 10**7 + 1000, image)
    ctx = context(tmp_path, "frames", name, inputs={"bag": path})
    return finished(ctx, KINDS.get("frames").handler(ctx))


@pytest.mark.slow
def test_recordings_to_a_trained_pilotnet_far_better_than_the_mean(tmp_path):
    torch.set_num_threads(2)
    deps = [record(tmp_path, f"circuit{c}_{d}", kind, seed=10 * c + i)
            for c, kind in ((0, "ros1"), (1, "sqlite3")) for i, d in enumerate(("cw", "ccw"))]
    ctx = context(tmp_path, "train", "train", {"epochs": 8, "batch_size": 32, "patience": 3,
                                               "augment": {"flip": True, "color_jitter": 0.2}},
                  deps={"frames": tuple(deps)})
    result = KINDS.get("train").handler(ctx)
    print({k: result[k] for k in ("val_mse", "val_mse_mean_predictor", "epochs_run", "best_epoch", "seconds")})
    assert result["val_mse"] < 0.2 * result["val_mse_mean_predictor"]
    model, checkpoint = load_checkpoint(ctx.out / "model.pt")
    assert checkpoint["history"][-1]["epoch"] == result["epochs_run"]
