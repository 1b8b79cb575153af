from __future__ import annotations

import dataclasses
import importlib.util

import pytest

from matrix.errors import UnknownNameError
from matrix.kinds import NotApplicable
from matrix.registry import DuplicateNameError
from pilotlab.errors import PilotlabError
from pilotlab.strategies import STRATEGIES, make_strategy_config, register_strategy, strategy_modules
from pilotlab.strategies.registry import StrategyEntry

STUDY = {"baseline", "dynamic_quant", "static_quant", "qat", "local_prune", "global_prune", "prune_quant"}
BEYOND = {"torchscript", "onnxruntime", "onnxruntime_int8", "bf16", "fp16", "structured_prune", "structured_prune_int8",
          "cluster", "tensorrt", "cuda_graph"}


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


@pytest.mark.parametrize("name", ["onnxruntime_int8", "structured_prune_int8"])
def test_a_calibration_method_is_checked_where_the_recipe_names_it(name):
    """Outside test: structured_prune_int8's `calibrate_method: foo` passed the plan and failed after its
    fine-tune, naming no recipe key (onnxruntime_int8's was refused at once)."""
    with pytest.raises(PilotlabError, match=f"strategies.{name}: calibrate_method.*'minmax', 'entropy' or 'percentile'"):
        make_strategy_config(name, {"calibrate_method": "foo"})


def test_unknown_strategy_suggests_the_closest():
    with pytest.raises(UnknownNameError, match="did you mean 'local_prune'"):
        make_strategy_config("local_prun", {})


def test_registering_twice_is_an_error():
    @dataclasses.dataclass(frozen=True)
    class Config:
        version: int = 1
    with pytest.raises(DuplicateNameError):
        register_strategy("baseline", Config, "pilotlab.strategies.baseline:baseline")


def test_a_config_without_version_is_refused():
    @dataclasses.dataclass(frozen=True)
    class Config:
        amount: float = 0.1
    with pytest.raises(TypeError, match="version"):
        register_strategy("unversioned", Config, "pilotlab.strategies.baseline:baseline")


def test_a_handler_is_named_module_colon_function():
    @dataclasses.dataclass(frozen=True)
    class Config:
        version: int = 1
    with pytest.raises(TypeError, match="package.module:function"):
        register_strategy("dotted", Config, "pilotlab.strategies.baseline.baseline")
    assert "dotted" not in STRATEGIES


@pytest.mark.parametrize("name", sorted(STRATEGIES))
def test_every_handler_is_a_function_of_its_module(name):
    entry = STRATEGIES.get(name)
    if any(importlib.util.find_spec(package) is None for package in entry.requires):
        pytest.skip(f"{name} needs {', '.join(entry.requires)}")
    assert callable(entry.handler) and entry.handler.__module__ == entry.module


def test_a_missing_requirement_is_not_applicable_before_the_handler_is_imported(trained, tmp_path):
    from pilotlab.strategies.apply import StrategySource, run_handler
    from pilotlab.strategies.configs.litert import LiteRTConfig
    entry = StrategyEntry("litert", LiteRTConfig, "no_such_package_xyz.handlers:run",
                          requires=("no_such_runtime_xyz",), extra="edge")
    with pytest.raises(NotApplicable, match=r"litert needs no_such_runtime_xyz, not installed here "
                                            r"\(pip install -e '\.\[edge\]'\)"):
        run_handler(entry, LiteRTConfig(), StrategySource(trained / "model.pt", tmp_path, strategy="litert"))


def test_code_fingerprint_is_the_strategy_modules_and_what_they_build_on():
    packages = {"pilotlab.strategies", "pilotlab.strategies.configs"}   # their __init__.py runs first
    assert strategy_modules("local_prune")[:1] == ["pilotlab.strategies.prune"]
    # local_prune loads its network from the l1_pruning prepare job: the loading code, not the shapers of the
    # other preparations (channels, stem, mot_torch: in their own modules, fingerprinted by their prepare jobs)
    prepared = {"pilotlab.strategies.prepared", "pilotlab.strategies.configs.prepare"}
    assert set(strategy_modules("local_prune")) == {"pilotlab.strategies.prune", "pilotlab.strategies.configs.prune",
                                                    *prepared, *packages}
    assert set(strategy_modules("prune_quant")) == {
        "pilotlab.strategies.prune_quant", "pilotlab.strategies.prune", "pilotlab.strategies.pt2e",
        "pilotlab.strategies.pt2e_graph", "pilotlab.strategies.configs.prune_quant",
        "pilotlab.strategies.configs.prune", "pilotlab.strategies.configs.pt2e", *prepared, *packages}
    assert set(strategy_modules("cluster")) == {"pilotlab.strategies.cluster", "pilotlab.strategies.kmeans",
                                                "pilotlab.strategies.configs.cluster", *packages}
    # the roots: the handler's module and the config's (read from the source: nothing is imported)
    assert STRATEGIES.get("litert").modules == ("pilotlab.strategies.litert", "pilotlab.strategies.configs.litert")
