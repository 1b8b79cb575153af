"""fit: learns a learnable task, stops early restoring the best weights, is seeded, reports progress."""
import numpy as np
import pytest
import torch

from pilotlab.data.augment import AugmentConfig
from pilotlab.data.frames import LabelRanges
from pilotlab.data.split import split_validation
from pilotlab.errors import PilotlabError
from pilotlab.models import build_model, make_config
from pilotlab.training import FitConfig, FitProgress, evaluate, fit, mean_predictor_mse
from tests.pilotlab.synthetic import stripe_frameset


@pytest.fixture(autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def split(data, fraction=0.25):
    s = split_validation(data.recording, fraction)
    return data.subset(s.train), data.subset(s.val)


def test_pilotnet_learns_where_the_stripe_is_far_better_than_the_mean():
    data = stripe_frameset(recordings=4, per_recording=24)
    train, val = split(data)
    ranges = LabelRanges.covering(data.labels)
    torch.manual_seed(0)
    model = build_model("pilotnet")
    history = fit(model, train, ranges, FitConfig(epochs=6, batch_size=8, lr=1e-3), val=val)
    val_mse, mean_mse = evaluate(model, val, ranges)["mse"], mean_predictor_mse(train, val, ranges)["mse"]
    print(f"val MSE {val_mse:.4f}, mean predictor {mean_mse:.4f}")
    assert val_mse < 0.25 * mean_mse
    assert val_mse == pytest.approx(min(r["val_loss"] for r in history), rel=1e-5)  # best weights restored


def test_early_stopping_stops_and_restores_the_best_epoch():
    data = stripe_frameset(recordings=2, per_recording=16)
    train, val = split(data, 0.5)
    ranges = LabelRanges.covering(data.labels)
    torch.manual_seed(0)
    model = build_model("pilotnet")
    # A learning rate this high makes the validation loss jump about, so it soon stops improving.
    history = fit(model, train, ranges, FitConfig(epochs=30, batch_size=8, lr=0.05, patience=2), val=val)
    best = min(history, key=lambda r: r["val_loss"])
    assert len(history) < 30 and len(history) == best["epoch"] + 2 and best.get("best")
    assert evaluate(model, val, ranges)["mse"] == pytest.approx(best["val_loss"], rel=1e-5)


def test_same_seed_same_history_with_augmentation():
    data = stripe_frameset(recordings=2, per_recording=12)
    ranges = LabelRanges.covering(data.labels)
    config = FitConfig(epochs=2, batch_size=8, lr=1e-3, seed=7,
                       augment=AugmentConfig(flip=True, color_jitter=0.2, blur=0.5, affine=0.5, oversample_curves=1))
    runs = []
    for _ in range(2):
        torch.manual_seed(7)
        model = build_model("pilotnet")
        runs.append([{k: v for k, v in r.items() if k != "seconds"} for r in fit(model, data, ranges, config)])
    assert runs[0] == runs[1]


def test_stacked_frames_model_trains_and_callbacks_report_progress():
    data = stripe_frameset(recordings=2, per_recording=10)
    train, val = split(data, 0.5)
    ranges = LabelRanges.covering(data.labels)
    model = build_model("pilotnet_stacked", make_config("pilotnet_stacked", {"frames": 2}))
    batches, epochs = [], []
    with FitProgress(2) as bar:
        def on_batch(*args):
            batches.append(args)
            bar.on_batch(*args)

        def on_epoch(row):
            epochs.append(row)
            bar.on_epoch(row)
        fit(model, train, ranges, FitConfig(epochs=2, batch_size=4, lr=1e-3, frames=2), val=val,
            on_epoch=on_epoch, on_batch=on_batch)
    assert [b[:3] for b in batches] == [(e, b, 3) for e in (1, 2) for b in (1, 2, 3)]
    assert [r["epoch"] for r in epochs] == [1, 2] and all(np.isfinite(r["val_loss"]) for r in epochs)


def test_a_diverging_training_is_an_error_not_a_nan_loss():
    from pilotlab.errors import PilotlabError
    data = stripe_frameset(recordings=2, per_recording=16)
    train, val = split(data, 0.5)
    torch.manual_seed(0)
    with pytest.raises(PilotlabError, match=r"training diverged: the (validation )?loss is (nan|inf) .*lower the learning rate \(lr 1e\+12\)"):
        fit(build_model("pilotnet"), train, LabelRanges.covering(data.labels), FitConfig(epochs=3, batch_size=8, lr=1e12), val=val)


def test_non_finite_labels_are_refused_before_training():
    from pilotlab.errors import PilotlabError
    data = stripe_frameset(recordings=2, per_recording=16)
    data.labels[5, 1] = np.inf
    with pytest.raises(PilotlabError, match=r"training data: 1 of 32 labels are not finite numbers \(first: frame 5 of recording 0"):
        fit(build_model("pilotnet"), data, LabelRanges((0, 1), (-1, 1)), FitConfig(epochs=1, batch_size=8, lr=1e-3))


class _NanNet(torch.nn.Module):
    def __init__(self):
        super().__init__()
        self.scale = torch.nn.Parameter(torch.ones(1))

    def forward(self, images):                      # [N, 3, H, W] -> [N, 2], NaN from the start
        return images.mean((1, 2, 3))[:, None].expand(-1, 2) * self.scale * float("nan")


class _NoWeights(torch.nn.Module):
    def forward(self, images):
        return images.mean((1, 2, 3))[:, None].expand(-1, 2)


@pytest.mark.parametrize("network, message", [
    (_NanNet, "output gives a loss of nan on the first batch, before any training step: check its forward pass"),
    (_NoWeights, "(_NoWeights) has no trainable parameters"),
])
def test_a_network_that_cannot_train_says_why_not_to_lower_the_learning_rate(network, message):
    """Outside test: a user's network NaN from the start was told to lower its learning rate, and one
    without parameters ended in torch's "optimizer got an empty parameter list"."""
    from pilotlab.errors import PilotlabError
    data = stripe_frameset(recordings=2, per_recording=16)
    with pytest.raises(PilotlabError, match=message.replace("(", r"\(").replace(")", r"\)")):
        fit(network(), data, LabelRanges((0, 1), (-1, 1)), FitConfig(epochs=1, batch_size=8, lr=1e-3))


class ViewsItsFeatures(torch.nn.Module):
    """A network of the user's as many are written: `.view(n, -1)` after the convolutions, which cannot
    view channels-last activations."""

    def __init__(self):
        super().__init__()
        self.conv = torch.nn.Conv2d(3, 4, 5, stride=4)
        self.head = torch.nn.Linear(4 * 16 * 49, 2)

    def forward(self, images):
        features = torch.relu(self.conv(images))
        return self.head(features.view(features.size(0), -1))


class Volumetric(torch.nn.Module):
    """A 3-D convolution (5-D weights, which have no channels-last layout) beside a 2-D one."""

    def __init__(self):
        super().__init__()
        self.conv2d = torch.nn.Conv2d(3, 3, 3, stride=4)
        self.conv3d = torch.nn.Conv3d(1, 2, 3, stride=2)
        self.head = torch.nn.LazyLinear(2)

    def forward(self, images):
        volume = self.conv3d(self.conv2d(images).unsqueeze(1))
        return self.head(volume.flatten(1))


@pytest.mark.parametrize("network", [ViewsItsFeatures, Volumetric, lambda: build_model("pilotnet")])
def test_fit_trains_networks_that_do_not_take_channels_last_and_leaves_every_weight_in_the_standard_layout(network):
    """Review finding: converting the whole model to channels-last while fitting broke a user's `.view(n, -1)`
    ("view size is not compatible") and any 5-D weight ("required rank 4 tensor"); the weights also
    have to come back in the standard layout for export."""
    data = stripe_frameset(recordings=2, per_recording=8)
    ranges = LabelRanges.covering(data.labels)
    torch.manual_seed(0)
    model = network()
    model(data.inputs(np.arange(2)))    # a lazy layer takes its shape
    history = fit(model, data, ranges, FitConfig(epochs=1, batch_size=8, lr=1e-3))
    assert len(history) == 1 and np.isfinite(history[0]["train_loss"])
    assert all(t.is_contiguous() for t in [*model.parameters(), *model.buffers()])


def test_bf16_mixed_precision_learns_as_well_and_keeps_float32_weights():
    """precision bf16: the forward pass under autocast, the weights (and what is saved) float32, and it learns:
    its validation loss well under the mean predictor's. On this tiny task (72 frames, 6 epochs) bf16 ended
    1.5-4.7x fp32's validation loss over seeds 0-4 (printed) on the AMD host; on the Intel host with AMX
    (2026-12-02) 0.24-4.5x, at 0.07-0.26x the mean predictor's (fp32: 0.05-0.29x; seed 0, this test's, 0.255
    and 0.124), so the bound is half the mean predictor's. On recorded driving data it was as good
    (quickstart test MSE 0.00218 against 0.00217, study 0.00329 against 0.00410), which is why
    `precision: fp32` exists and the report states the precision."""
    data = stripe_frameset(recordings=4, per_recording=24)
    train, val = split(data)
    ranges = LabelRanges.covering(data.labels)
    losses = {}
    for precision in ("fp32", "bf16"):
        torch.manual_seed(0)
        model = build_model("pilotnet")
        history = fit(model, train, ranges, FitConfig(epochs=6, batch_size=8, lr=1e-3, precision=precision), val=val)
        assert {row["precision"] for row in history} == {precision}
        assert all(t.dtype == torch.float32 for t in model.state_dict().values() if t.is_floating_point())
        losses[precision] = evaluate(model, val, ranges)["mse"]
    print(losses)
    assert losses["bf16"] < 0.5 * mean_predictor_mse(train, val, ranges)["mse"]


@pytest.mark.parametrize("native", [True, False])
def test_auto_precision_is_bf16_only_where_the_cpu_computes_it_natively(monkeypatch, native):
    import pilotlab.training as training
    monkeypatch.setattr(training, "native_cpu_dtype", lambda dtype: native and dtype == "bfloat16")
    assert training.fit_precision("auto") == ("bf16" if native else "fp32")
    assert training.fit_precision("fp32") == "fp32" and training.fit_precision("bf16") == "bf16"
    with pytest.raises(PilotlabError, match="not one of auto, fp32, bf16"):
        training.fit_precision("fp16")


class Float32Head(torch.nn.Module):
    """A network of the user's that autocast breaks: its head insists on float32 features."""

    def __init__(self):
        super().__init__()
        self.conv = torch.nn.Conv2d(3, 4, 5, stride=4)
        self.head = torch.nn.Linear(4 * 16 * 49, 2)

    def forward(self, images):
        features = torch.relu(self.conv(images)).flatten(1)
        if features.dtype != torch.float32:
            raise TypeError(f"features are {features.dtype}, the head takes float32")
        return self.head(features)


def test_auto_precision_trains_in_fp32_a_network_autocast_breaks(monkeypatch):
    import pilotlab.training as training
    monkeypatch.setattr(training, "native_cpu_dtype", lambda dtype: True)
    data = stripe_frameset(recordings=2, per_recording=8)
    ranges = LabelRanges.covering(data.labels)
    torch.manual_seed(0)
    history = fit(Float32Head(), data, ranges, FitConfig(epochs=1, batch_size=8, lr=1e-3, precision="auto"))
    assert history[0]["precision"] == "fp32" and np.isfinite(history[0]["train_loss"])
    with pytest.raises(TypeError, match="the head takes float32"):   # asked for explicitly, it is not hidden
        fit(Float32Head(), data, ranges, FitConfig(epochs=1, batch_size=8, lr=1e-3, precision="bf16"))
