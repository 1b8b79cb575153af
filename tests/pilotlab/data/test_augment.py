"""Batch augmentation: what each transform does, and that it is seeded."""
import numpy as np
import pytest
import torch

from pilotlab.data.augment import AugmentConfig, augment_batch, epoch_order
from pilotlab.errors import PilotlabError


def batch(n=16, channels=3):
    images = torch.rand(n, channels, 66, 200, generator=torch.Generator().manual_seed(1))
    labels = torch.stack([torch.full((n,), 4.0), torch.linspace(-1, 1, n)], 1)
    return images, labels


def test_nothing_selected_changes_nothing():
    images, labels = batch()
    out, out_labels = augment_batch(images, labels, AugmentConfig(), torch.Generator())
    assert out is images and out_labels is labels


def test_flip_mirrors_images_and_negates_w_only():
    images, labels = batch(64)
    out, out_labels = augment_batch(images, labels, AugmentConfig(flip=True), torch.Generator().manual_seed(0))
    flipped = out_labels[:, 1] != labels[:, 1]
    assert 10 < int(flipped.sum()) < 54
    assert torch.equal(out[flipped], images[flipped].flip(-1)) and torch.equal(out[~flipped], images[~flipped])
    assert torch.equal(out_labels[flipped, 1], -labels[flipped, 1]) and torch.equal(out_labels[:, 0], labels[:, 0])


def test_stacked_frames_get_the_same_flip():
    images, labels = batch(8, channels=9)
    out, out_labels = augment_batch(images, labels, AugmentConfig(flip=True), torch.Generator().manual_seed(0))
    assert torch.equal(out, torch.where((out_labels[:, 1] != labels[:, 1]).view(-1, 1, 1, 1), images.flip(-1), images))


@pytest.mark.parametrize("config", [AugmentConfig(color_jitter=0.3), AugmentConfig(blur=1.0), AugmentConfig(affine=1.0)])
def test_photometric_and_affine_keep_shape_and_range_and_labels(config):
    images, labels = batch()
    out, out_labels = augment_batch(images, labels, config, torch.Generator().manual_seed(0))
    assert out.shape == images.shape and torch.equal(out_labels, labels)
    assert float(out.min()) >= 0 and float(out.max()) <= 1
    assert not torch.equal(out, images)


def test_blur_smooths():
    images, labels = batch()
    out, _ = augment_batch(images, labels, AugmentConfig(blur=1.0), torch.Generator().manual_seed(0))
    assert float(out.diff(dim=-1).abs().mean()) < 0.8 * float(images.diff(dim=-1).abs().mean())
    assert float(out.mean()) == pytest.approx(float(images.mean()), abs=0.01)


def test_same_seed_same_batch():
    images, labels = batch()
    config = AugmentConfig(flip=True, color_jitter=0.2, blur=0.5, affine=0.5)
    a = augment_batch(images, labels, config, torch.Generator().manual_seed(3))
    b = augment_batch(images, labels, config, torch.Generator().manual_seed(3))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])


def test_oversampling_repeats_curve_frames():
    w = np.array([0.0, 0.1, -0.9, 1.0, 0.05])
    order = epoch_order(w, 1.0, AugmentConfig(oversample_curves=2), np.random.default_rng(0))
    assert sorted(np.bincount(order, minlength=5)) == [1, 1, 1, 3, 3]
    assert set(order[np.bincount(order)[order] == 3]) == {2, 3}
    partial = epoch_order(w, 1.0, AugmentConfig(oversample_curves=0.5), np.random.default_rng(0))
    assert len(w) <= len(partial) <= len(w) + 2
    assert sorted(epoch_order(w, 1.0, AugmentConfig(), np.random.default_rng(0))) == list(range(5))


def test_unknown_or_bad_options_are_refused():
    with pytest.raises(PilotlabError, match="augment: unknown param 'flipp' .did you mean 'flip'..; known: affine, blur"):
        AugmentConfig.from_job_params({"flipp": True}, "augment")
    with pytest.raises(PilotlabError, match="augment: blur: Input should be less than or equal to 1"):
        AugmentConfig.from_job_params({"blur": 2}, "augment")
