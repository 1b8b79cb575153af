"""The networks: PilotNet as DeepLearningStudio's PyTorch version, and PilotNetStacked."""
import pytest
import torch
from torch import nn

from pilotlab.errors import PilotlabError, UnknownNameError
from pilotlab.models import MODELS, build_model, input_frames, load_checkpoint, make_config, save_checkpoint


def layers(model):
    return [(type(m).__name__, getattr(m, "in_channels", getattr(m, "in_features", getattr(m, "num_features", None))),
             getattr(m, "out_channels", getattr(m, "out_features", None)), getattr(m, "kernel_size", None),
             getattr(m, "stride", None)) for m in model.modules() if not list(m.children())]


def test_pilotnet_is_deeplearningstudios():
    model = build_model("pilotnet")
    assert layers(model) == [
        ("BatchNorm2d", 3, None, None, None),
        ("Conv2d", 3, 24, (5, 5), (2, 2)), ("ReLU", None, None, None, None),
        ("Conv2d", 24, 36, (5, 5), (2, 2)), ("ReLU", None, None, None, None),
        ("Conv2d", 36, 48, (5, 5), (2, 2)), ("ReLU", None, None, None, None),
        ("Conv2d", 48, 64, (3, 3), (1, 1)), ("ReLU", None, None, None, None),
        ("Conv2d", 64, 64, (3, 3), (1, 1)), ("ReLU", None, None, None, None),
        ("Flatten", None, None, None, None),
        ("Linear", 1152, 1164, None, None), ("ReLU", None, None, None, None),
        ("Linear", 1164, 100, None, None), ("ReLU", None, None, None, None),
        ("Linear", 100, 50, None, None), ("ReLU", None, None, None, None),
        ("Linear", 50, 10, None, None), ("ReLU", None, None, None, None),
        ("Linear", 10, 2, None, None)]
    assert model.input_norm.eps == pytest.approx(1e-3)
    assert sum(p.numel() for p in model.parameters()) == 1_595_528
    assert model(torch.rand(2, 3, 66, 200)).shape == (2, 2)


@pytest.mark.parametrize("arch", ["pilotnet", "pilotnet_stacked"])
def test_the_input_norm_s_scale_and_shift_are_not_trained_and_the_first_conv_absorbs_any(arch):
    """Training leaves the input BatchNorm's scale and shift as they are (their gradient would be the first
    convolution's whole input gradient) while its running statistics follow the data; nothing is lost:
    the first convolution, without padding, computes any scale and shift into its own weights exactly."""
    torch.manual_seed(0)
    model = build_model(arch).train()
    norm, conv = model.input_norm, model.features[0]
    images = torch.rand(8, norm.num_features, 66, 200)
    optimizer = torch.optim.Adam([p for p in model.parameters() if p.requires_grad])
    model(images).square().mean().backward()
    optimizer.step()
    assert conv.padding == (0, 0) and not norm.weight.requires_grad and not norm.bias.requires_grad
    assert torch.equal(norm.weight, torch.ones_like(norm.weight)) and torch.equal(norm.bias, torch.zeros_like(norm.bias))
    assert not torch.allclose(norm.running_mean, torch.zeros_like(norm.running_mean))

    model.eval()
    with torch.no_grad():
        norm.weight.uniform_(0.5, 2.0), norm.bias.uniform_(-0.5, 0.5)
        before = model(images)
        scale, shift = norm.weight.clone(), norm.bias.clone()
        conv.bias += (conv.weight * shift[None, :, None, None]).sum((1, 2, 3))
        conv.weight *= scale[None, :, None, None]
        norm.weight.fill_(1.0), norm.bias.zero_()
        assert torch.allclose(model(images), before, atol=1e-5)


@pytest.mark.parametrize("arch", ["pilotnet", "pilotnet_stacked"])
def test_no_seed_starts_with_a_dead_bottleneck(arch):
    """With torch's default initialisation, seed 1 started PilotNet with all ten units of its 10-wide
    layer dead: it output a constant and never learned. He initialisation keeps them alive."""
    for seed in range(12):
        torch.manual_seed(seed)
        model = build_model(arch).train()
        images = torch.rand(32, model.input_norm.num_features, 66, 200)
        with torch.no_grad():
            bottleneck = model.head[:-1](model.features(model.input_norm(images)))   # [32, 10] after the ReLU
        assert (bottleneck > 0).any(0).sum() >= 5, f"seed {seed}"
        assert model(images).std(0).min() > 0


def test_pilotnet_dropout_is_an_option():
    model = build_model("pilotnet", make_config("pilotnet", {"dropout": 0.3}))
    assert [m.p for m in model.modules() if isinstance(m, nn.Dropout)] == [0.3]


def test_pilotnet_stacked_takes_consecutive_frames_on_the_channels():
    config = make_config("pilotnet_stacked", {"frames": 3})
    model = build_model("pilotnet_stacked", config)
    assert input_frames(config) == 3 and input_frames(make_config("pilotnet")) == 1
    assert model.input_norm.num_features == 9 and model.features[0].in_channels == 9
    assert sum(p.numel() for p in model.parameters()) == 1_599_140
    assert model(torch.rand(2, 9, 66, 200)).shape == (2, 2)
    with pytest.raises(PilotlabError, match="frames = 0 must be at least 1"):
        make_config("pilotnet_stacked", {"frames": 0})


def test_registry_lists_both_and_suggests_names():
    assert {"pilotnet", "pilotnet_stacked"} <= set(MODELS.names())
    with pytest.raises(UnknownNameError, match="did you mean 'pilotnet_stacked'"):
        build_model("pilotnet_stackd")


def test_checkpoint_round_trip_keeps_config_and_extras(tmp_path):
    config = make_config("pilotnet_stacked", {"frames": 2})
    model = build_model("pilotnet_stacked", config).eval()
    save_checkpoint(tmp_path / "m.pt", model, "pilotnet_stacked", config, labels={"v": [0, 1], "w": [-1, 1]})
    loaded, payload = load_checkpoint(tmp_path / "m.pt")
    x = torch.rand(1, 6, 66, 200)
    assert torch.equal(loaded(x), model(x)) and loaded.config == config and payload["labels"]["w"] == [-1, 1]
