from __future__ import annotations

import dataclasses

import pytest

from matrix.errors import UnknownNameError
from matrix.registry import DuplicateNameError
from pilotlab.errors import PilotlabError
from pilotlab.strategies import STRATEGIES, make_strategy_config, register_strategy, strategy_modules

STUDY = {"baseline", "dynamic_quant", "static_quant", "qat", "local_prune", "global_prune", "prune_quant"}
BEYOND = {"torchscript", "onnxruntime", "onnxruntime_int8", "bf16", "fp16", "structured_prune", "structured_prune_int8",
          "cluster", "tensorrt"}


def test_the_study_set_and_beyond_are_registered():
    assert STUDY | BEYOND <= set(STRATEGIES)


@pytest.mark.parametrize("name", sorted(STUDY | BEYOND))
def test_configs_are_frozen_versioned_dataclasses(name):
    config = make_strategy_config(name, {})
    assert dataclasses.is_dataclass(config) and config.version >= 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.version = 99


def test_options_from_the_recipe_are_typed():
    config = make_strategy_config("local_prune", {"conv": 0.2, "linear": 1 / 4, "finetune_epochs": 3})
    assert (config.conv, config.linear, config.finetune_epochs) == (0.2, 0.25, 3)


def test_unknown_option_names_the_strategy_and_its_options():
    with pytest.raises(PilotlabError, match=r"strategies.local_prune: unknown option\(s\) amount; "
                                            r"known: conv, linear"):
        make_strategy_config("local_prune", {"amount": 0.3})


def test_wrong_type_is_an_error_naming_the_option():
    with pytest.raises(PilotlabError, match="strategies.global_prune: amount"):
        make_strategy_config("global_prune", {"amount": "lots"})


def test_unknown_strategy_suggests_the_closest():
    with pytest.raises(UnknownNameError, match="did you mean 'local_prune'"):
        make_strategy_config("local_prun", {})


def test_registering_twice_is_an_error():
    @dataclasses.dataclass(frozen=True)
    class Config:
        version: int = 1
    with pytest.raises(DuplicateNameError):
        register_strategy("baseline", Config)(lambda config, source: {})


def test_a_config_without_version_is_refused():
    @dataclasses.dataclass(frozen=True)
    class Config:
        amount: float = 0.1
    with pytest.raises(TypeError, match="version"):
        register_strategy("unversioned", Config)


def test_code_fingerprint_is_the_strategy_module_and_what_it_builds_on():
    assert strategy_modules("local_prune") == ["pilotlab.strategies.prune"]
    assert set(strategy_modules("prune_quant")) == {
        "pilotlab.strategies.prune_quant", "pilotlab.strategies.prune", "pilotlab.strategies.pt2e",
        "pilotlab.strategies.pt2e_graph"}
    # helpers a handler imports inside a function count too
    assert set(strategy_modules("cluster")) == {"pilotlab.strategies.cluster", "pilotlab.strategies.kmeans"}
