"""Every definition of a recipe is validated, whether the matrix uses it or not ("every key is
validated"): a strategy, model, dataset, hardware profile or circuit the matrix does not name yet
gets the same one-line error it would get in use. Names, options and that files exist are checked;
no user file is hashed, so an unused definition costs planning next to nothing."""
from __future__ import annotations

from pathlib import Path

from matrix.errors import MatrixError, UnknownNameError, did_you_mean


def check_definitions(planner) -> None:
    """Each definition of `planner`'s recipe (a pilotlab.planning.Planner), as it would be checked in use."""
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
        if planner.latency_file(name) is not None:
            planner.check_latency_file(name)
    for name, circuit in config.circuits.items():
        _check_circuit_name(planner.recipe, name)
        planner.path(circuit.csv, ["circuits", name, "csv"], "file")


def _check_circuit_name(recipe, name: str) -> None:
    """A recipe's circuit does not take a built-in's name: every lap and row named so would be driven on
    the user's file (a CSV named so beside the recipe is refused the same way: pilotlab.circuits.registry)."""
    from pilotlab.circuits.registry import CIRCUITS
    if name in CIRCUITS:
        raise recipe.error(f"{name!r} is the name of a built-in circuit, which a recipe's circuit does not "
                           f"replace; give yours another name (e.g. my_{name}) and use that name in the matrix",
                           ["circuits", name])


def _check_model(planner, name: str, spec) -> None:
    from pilotlab import usercode
    check_arch(planner.recipe, name, spec)
    if spec.data not in planner.config.datasets:
        raise planner.recipe.error(f"dataset {spec.data!r} is not defined"
                                   f"{did_you_mean(spec.data, planner.config.datasets)}; datasets: "
                                   f"{', '.join(planner.config.datasets) or '(none)'}", ["models", name, "data"])
    for key in ("weights", "torchscript", "onnx"):
        if getattr(spec, key) is not None:
            planner.path(getattr(spec, key), ["models", name, key], "file")
    if spec.network is not None:
        try:
            usercode.source_files(spec.network, planner.folder)
            usercode.check_source(spec.network, planner.folder, spec.options)
        except MatrixError as error:
            raise planner.recipe.error(str(error), ["models", name, "network"]) from None


def check_arch(recipe, name: str, spec) -> None:
    """A built-in arch's name and options (a model the user brings is checked by its files)."""
    from pilotlab.models import make_config
    from pilotlab.models.imported import IMPORTED_ARCHS
    if spec.source != "arch":
        return
    if spec.arch in IMPORTED_ARCHS:
        raise recipe.error(f"arch {spec.arch!r} names checkpoints of models you bring; write `{spec.arch}: ...` "
                           f"(e.g. network: nets/mine.py:MyNet) instead of `arch`", ["models", name, "arch"])
    try:
        make_config(spec.arch, spec.options)
    except UnknownNameError:   # the recipe's archs, not the registry's (which holds the checkpoints of user models)
        from pilotlab.models import MODELS
        archs = [arch for arch in MODELS.names() if arch not in IMPORTED_ARCHS]
        raise recipe.error(f"unknown arch {spec.arch!r}{did_you_mean(spec.arch, archs)}; built-in archs: "
                           f"{', '.join(archs)} (or bring your own: network, torchscript or onnx instead of arch, "
                           "docs/own-network.md)", ["models", name, "arch"]) from None
    except MatrixError as error:
        raise recipe.error(str(error), ["models", name]) from None


def _check_dataset(planner, name: str, spec) -> None:
    for key in ("bags", "folders"):
        for path in getattr(spec, key):
            planner.path(path, ["datasets", name, key], "recording")
    for circuit in spec.record.circuits if spec.record is not None else ():
        if circuit not in planner.config.circuits:
            planner.circuit_param(circuit, ["datasets", name, "record", "circuits"])


BAG_SUFFIXES = (".bag", ".db3", ".mcap")


def path_problem(path: Path, expect: str) -> str | None:
    """What is wrong with an existing input path for what the recipe expects there, or None; checked
    before it is hashed, so a folder given for a file (`/root`) fails at once, not after hashing it all.
    "file": a regular file; "recording": a ROS1 .bag (or ROS2 .db3/.mcap) file, or a folder holding
    metadata.yaml (a ROS2 bag) or data.csv (a DeepLearningStudio dataset folder)."""
    from matrix.inputhash import system_root
    if system_root(path.resolve()):   # hashing refuses it, saying so
        return None
    if expect == "file" and not path.is_file():
        return "is a folder; give a file" if path.is_dir() else "is not a regular file"
    if expect == "recording" and path.is_dir():
        if not ((path / "metadata.yaml").is_file() or (path / "data.csv").is_file()):
            return ("is a folder holding neither metadata.yaml (a ROS2 bag) nor data.csv (a DeepLearningStudio "
                    "dataset folder); name the recording's own folder")
    elif expect == "recording" and path.suffix not in BAG_SUFFIXES:
        return f"is not a bag: a ROS1 bag ends in .bag, a ROS2 bag is a folder (or its {' / '.join(BAG_SUFFIXES[1:])} file)"
    return None
