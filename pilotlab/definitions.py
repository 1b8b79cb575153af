"""Every definition of a recipe is validated, whether the matrix uses it or not ("every key is
validated"): a strategy, model, dataset, hardware profile or circuit the matrix does not name yet
gets the same one-line error it would get in use. Names, options and that files exist are checked;
no user file is hashed, so an unused definition costs planning next to nothing."""
from __future__ import annotations

from typing import TYPE_CHECKING

from matrix.errors import MatrixError

if TYPE_CHECKING:
    from pilotlab.domain import Planner


def check_definitions(planner: Planner) -> None:
    config = planner.config
    for name in config.strategies:
        planner.strategy(name)
    for name, spec in config.models.items():
        _check_model(planner, name, spec)
    for name, spec in config.datasets.items():
        _check_dataset(planner, name, spec)
    for name in config.hardware:
        try:
            planner.profile(name)
        except MatrixError as error:
            raise planner.recipe.error(str(error).removeprefix(f"hardware.{name}").lstrip(".: "),
                                       ["hardware", name]) from None
        planner.latency_file(name)
    for name, circuit in config.circuits.items():
        planner.path(circuit.csv, ["circuits", name, "csv"])


def _check_model(planner: Planner, name: str, spec) -> None:
    from pilotlab import usercode
    from pilotlab.domain import _check_model as check_arch
    check_arch(planner.recipe, name, spec)
    if spec.data not in planner.config.datasets:
        raise planner.recipe.error(f"dataset {spec.data!r} is not defined; datasets: "
                                   f"{', '.join(planner.config.datasets) or '(none)'}", ["models", name, "data"])
    for key in ("weights", "torchscript", "onnx"):
        if getattr(spec, key) is not None:
            planner.path(getattr(spec, key), ["models", name, key])
    if spec.network is not None:
        try:
            usercode.source_files(spec.network, planner.folder)
        except MatrixError as error:
            raise planner.recipe.error(str(error), ["models", name, "network"]) from None


def _check_dataset(planner: Planner, name: str, spec) -> None:
    for key in ("bags", "folders"):
        for path in getattr(spec, key):
            planner.path(path, ["datasets", name, key])
    for circuit in spec.record.circuits if spec.record is not None else ():
        if circuit not in planner.config.circuits:
            planner.circuit_param(circuit, ["datasets", name, "record", "circuits"])
