"""The exported graph's train/eval switch (pilotlab/strategies/pt2e_graph.py): a graph with dropout is
switched as torchao does; a graph without dropout or batch norm is left alone (its switch is skipped)."""
import pytest
import torch
from torch import nn

from pilotlab.strategies import pt2e_graph
from pilotlab.strategies.pt2e_graph import TrainEvalSwitch, export_graph


def exported(*layers: nn.Module) -> torch.fx.GraphModule:
    torch.manual_seed(0)
    return export_graph(nn.Sequential(nn.Flatten(), nn.Linear(12, 16), *layers, nn.Linear(16, 2)).train(),
                        (None, 3, 2, 2))


def test_a_graph_with_dropout_drops_in_training_and_not_in_evaluation():
    switch = TrainEvalSwitch(exported(nn.Dropout(0.5)))
    images = torch.rand(64, 3, 2, 2)
    switch.eval()
    assert torch.equal(switch(images), switch(images))
    switch.train()
    assert not torch.equal(switch(images), switch(images))


def test_a_graph_without_dropout_or_batch_norm_is_not_rewritten(monkeypatch):
    def rewrite(graph):
        raise AssertionError("switched a graph that has nothing to switch")
    monkeypatch.setattr(pt2e_graph, "move_exported_model_to_eval", rewrite)
    monkeypatch.setattr(pt2e_graph, "move_exported_model_to_train", rewrite)
    switch = TrainEvalSwitch(exported(nn.ReLU()))
    assert not switch.eval().training and switch.train().training
    with pytest.raises(AssertionError, match="nothing to switch"):
        TrainEvalSwitch(exported(nn.Dropout(0.5))).eval()
