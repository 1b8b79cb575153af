"""Channel surgery (pilotlab.strategies.channels): which channels a layer keeps. With training frames, the
ones whose output reaches the next layer most; without, the ones of largest L1 weight norm."""
from __future__ import annotations

import pytest
import torch
from torch import nn

from pilotlab.errors import PilotlabError
from pilotlab.strategies.channels import remove_channels
from pilotlab.strategies.registry import make_strategy_config


def _dead_unit_net() -> nn.Module:
    """[N, 4] -> 4 hidden units -> [N, 2]; unit 0 has the largest weights but a bias that keeps it off on
    inputs in [0, 1], so it never fires; units 1-3 do."""
    torch.manual_seed(0)
    model = nn.Sequential(nn.Linear(4, 4), nn.ReLU(), nn.Linear(4, 2))
    with torch.no_grad():
        model[0].weight.copy_(torch.tensor([[5.0, 5.0, 5.0, 5.0], [0.5, 0.1, 0.2, 0.3],
                                            [0.2, 0.6, 0.1, 0.1], [0.1, 0.2, 0.4, 0.3]]))
        model[0].bias.copy_(torch.tensor([-50.0, 0.1, 0.1, 0.1]))
    return model.eval()


def _first_layer_rows(model: nn.Module) -> list[list[float]]:
    return model[0].weight.detach().tolist()


def test_a_unit_that_never_fires_goes_whatever_its_weights():
    sample = torch.rand(64, 4, generator=torch.Generator().manual_seed(1))
    original, by_output, by_weights = _dead_unit_net(), _dead_unit_net(), _dead_unit_net()
    remove_channels(by_output, 0.25, (1, 4), sample=sample)
    remove_channels(by_weights, 0.25, (1, 4))
    assert [5.0] * 4 not in _first_layer_rows(by_output)
    assert [5.0] * 4 in _first_layer_rows(by_weights)          # L1 keeps the dead unit, drops a live one
    with torch.no_grad():                                     # the dead unit gave nothing: nothing changed
        assert torch.allclose(by_output(sample), original(sample))
        assert not torch.allclose(by_weights(sample), original(sample))


def test_a_conv_channel_the_next_layer_ignores_goes_whatever_its_weights():
    """Channel 1 has the largest weights, but the next layer (a linear after a flatten, a block of H×W
    inputs per channel) gives it none: it contributes nothing and goes."""
    torch.manual_seed(0)
    model = nn.Sequential(nn.Conv2d(3, 4, 3), nn.ReLU(), nn.Flatten(), nn.Linear(4 * 4 * 4, 2)).eval()
    with torch.no_grad():
        model[0].weight[1] = 1.0
        model[0].bias.fill_(0.1)
        model[3].weight.view(2, 4, 16)[:, 1] = 0.0
    strongest = model[0].weight.detach()[1].clone()
    sample = torch.rand(32, 3, 6, 6, generator=torch.Generator().manual_seed(1))
    kept = remove_channels(model, 0.25, (1, 3, 6, 6), sample=sample)
    assert kept == {"0": 3}
    assert not any(torch.equal(row, strongest) for row in model[0].weight.detach())
    assert model[3].weight.shape == (2, 3 * 16)


def test_criterion_is_an_option_checked_when_the_recipe_is_read():
    assert make_strategy_config("structured_prune", {}).criterion == "activation"
    assert make_strategy_config("structured_prune_int8", {"criterion": "l1"}).criterion == "l1"
    with pytest.raises(PilotlabError, match="criterion.*'activation' or 'l1'"):
        make_strategy_config("structured_prune", {"criterion": "l2"})
