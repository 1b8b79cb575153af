"""The driving domain as the engine sees it: recipe sections, axes, and the planner.

A recipe becomes jobs, shared wherever their inputs are equal:

    record (per recording) -> frames (per recording) -> train (per model)
        -> optimize (per model × strategy) -> offline (per model × strategy × hardware)
                                           -> online  (per model × strategy × hardware × circuit × direction)
    plus reference laps (explicit brain, expert) per hardware × circuit × direction.

Relative paths in a recipe (bags, dataset folders, circuit CSVs) are relative to the recipe's folder.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from matrix.errors import MatrixError, did_you_mean
from matrix.jobs import Job, input_file
from matrix.recipe import Domain, Recipe
from pilotlab.recipe import SECTIONS, DatasetSpec, ModelSpec

AXES = ("model", "strategy", "hardware", "circuit")
HARDWARE_DEPENDENT_STRATEGY_MODULES = ("pilotlab.strategies.half", "pilotlab.strategies.cuda")


# --- axes: which names a combination may carry -------------------------------------------------

def _models(config) -> list[str]:
    return list(config.models)


def _strategies(config) -> list[str]:
    from pilotlab.strategies import STRATEGIES
    return sorted(set(STRATEGIES.names()) | set(config.strategies))


def _hardware(config) -> list[str]:
    from pilotlab.hardware import BUILTIN
    return sorted(set(BUILTIN) | set(config.hardware))


def _circuits(config) -> list[str]:
    from pilotlab.circuits import all_circuit_names
    return sorted(set(all_circuit_names()) | set(config.circuits))


# --- the planner -------------------------------------------------------------------------------

class Planner:
    def __init__(self, recipe: Recipe):
        self.recipe, self.config = recipe, recipe.config
        self.folder = Path(recipe.file).resolve().parent
        self.datasets: dict[str, list[Job]] = {}
        self.trained: dict[str, Job] = {}
        self.optimized: dict[tuple, Job] = {}

    def jobs(self) -> list[Job]:
        jobs: list[Job] = []
        for combination in self.recipe.combinations:
            jobs += self.combination_jobs(combination)
        jobs += self.reference_jobs()
        return jobs

    def combination_jobs(self, combination: dict[str, Any]) -> list[Job]:
        missing = [axis for axis in ("model", "strategy") if axis not in combination]
        if missing:
            raise self.recipe.error(f"the combination {combination} has no {' and no '.join(missing)}; "
                                    "every combination needs a model and a strategy", ["matrix"])
        hardware = str(combination.get("hardware", "cpu"))
        optimize = self.optimize(str(combination["model"]), str(combination["strategy"]), hardware)
        jobs = [self.offline(optimize, combination, hardware)]
        if "circuit" in combination:
            jobs += online_jobs(self, optimize, combination, hardware)
        return jobs

    # datasets -----------------------------------------------------------------------------------
    def dataset(self, name: str, used_by: list) -> list[Job]:
        if name not in self.config.datasets:
            raise self.recipe.error(f"dataset {name!r} is not defined; datasets: "
                                    f"{', '.join(self.config.datasets) or '(none)'}", used_by)
        if name not in self.datasets:
            self.datasets[name] = self._dataset_jobs(name, self.config.datasets[name])
        return self.datasets[name]

    def _dataset_jobs(self, name: str, spec: DatasetSpec) -> list[Job]:
        topics = {k: v for k, v in (("image_topic", spec.topics.image), ("command_topic", spec.topics.command))
                  if v is not None}
        jobs = []
        if spec.record is not None:
            for label, record in self._recordings(name, spec):
                jobs.append(Job("frames", f"frames {label}", {**topics, "label": label}, deps={"bag": record}))
        for i, path in enumerate(spec.bags + spec.folders):
            source = self.path(path, ["datasets", name, "bags" if i < len(spec.bags) else "folders"])
            label = f"{name}/{Path(path).name}"
            jobs.append(Job("frames", f"frames {label}", {**topics, "label": label},
                            inputs={"bag": input_file(str(source))}))
        return jobs

    def _recordings(self, name: str, spec: DatasetSpec) -> list[tuple[str, Job]]:
        """(label, record job) for every circuit and direction of the dataset."""
        record = spec.record
        jobs = []
        for circuit in record.circuits:
            params, inputs = self.circuit_param(circuit, ["datasets", name, "record", "circuits"])
            for direction in record.directions:
                label = f"{name}/{circuit} {direction}"
                jobs.append((label, Job("record", f"record {label}", {
                    **params, "direction": direction, "laps": record.laps,
                    "seed": record.seed, "width": record.camera.width, "height": record.camera.height,
                    "rate_hz": record.rate_hz, "format": record.format,
                    "compressed": "jpeg" if record.compressed else None, "noise": record.noise},
                    inputs=inputs)))
        return jobs

    def circuit_param(self, circuit: str, where: list) -> tuple[dict, dict]:
        """(params, inputs) naming a circuit: a recipe-defined CSV is an input file (content hashed)."""
        if circuit in self.config.circuits:
            csv = self.path(self.config.circuits[circuit].csv, ["circuits", circuit, "csv"])
            return {"circuit": str(csv)}, {"circuit_csv": input_file(str(csv))}
        from pilotlab.circuits import csv_path_of
        try:
            csv = csv_path_of(circuit)
        except MatrixError as error:
            raise self.recipe.error(str(error), where) from None
        return {"circuit": circuit}, ({"circuit_csv": input_file(str(csv))} if csv else {})

    def path(self, value: str, where: list) -> Path:
        from matrix.fingerprint import shown_path
        try:
            path = Path(value).expanduser()
            path = path if path.is_absolute() else self.folder / path
            exists = path.exists()
        except (OSError, ValueError, RuntimeError) as error:   # too long, a NUL byte, an unknown ~user
            raise self.recipe.error(f"{shown_path(Path(value))} cannot be a path: "
                                    f"{getattr(error, 'strerror', None) or error}", where) from None
        if not exists:
            raise self.recipe.error(f"{shown_path(Path(value))} does not exist (looked for {shown_path(path)}; relative "
                                    "paths are relative to the recipe's folder)", where)
        return path

    # models and strategies ------------------------------------------------------------------------
    def train(self, model: str) -> Job:
        if model not in self.trained:
            spec: ModelSpec = self.config.models[model]
            frames = self.dataset(spec.data, ["models", model, "data"])
            _check_model(self.recipe, model, spec)
            params = spec.model_dump(exclude={"data"})
            self.trained[model] = Job("train", f"train {model}", params, deps={"frames": tuple(frames)})
        return self.trained[model]

    def optimize(self, model: str, strategy: str, hardware: str) -> Job:
        base, options = self.strategy(strategy)
        params: dict[str, Any] = {"strategy": base, "options": options}
        if _hardware_dependent(base):
            from pilotlab.hardware import host_fingerprint
            profile = self.profile(hardware)
            params |= {"hardware": {"name": profile.device, "device": profile.device, "threads": None},
                       "host": host_fingerprint()}
        slot = (model, strategy, params.get("hardware", {}).get("device"))
        if slot not in self.optimized:
            train = self.train(model)
            suffix = f" for {params['hardware']['device']}" if "hardware" in params else ""
            self.optimized[slot] = Job("optimize", f"optimize {model}/{strategy}{suffix}", params,
                                       deps={"model": train, "calibration": train.deps["frames"]})
        return self.optimized[slot]

    def strategy(self, name: str) -> tuple[str, dict[str, Any]]:
        """(registered strategy, options) for a strategy name of the recipe (aliases via `use:`)."""
        from pilotlab.strategies import STRATEGIES, make_strategy_config
        options = dict(self.config.strategies.get(name, {}))
        base = options.pop("use", name)
        where = ["strategies", name]
        if not isinstance(base, str):
            kind = {list: "a list", dict: "a mapping", type(None): "nothing"}.get(type(base), type(base).__name__)
            raise self.recipe.error(f"`use` names one strategy (got {kind}); e.g. use: local_prune", where + ["use"])
        if base not in STRATEGIES:
            raise self.recipe.error(f"unknown strategy {base!r}{did_you_mean(base, STRATEGIES.names())}; "
                                    f"known: {', '.join(sorted(STRATEGIES.names()))}", where + ["use"])
        if base != name and name in STRATEGIES:
            raise self.recipe.error(f"{name!r} is a built-in strategy; give the variant of {base} a new name",
                                    where + ["use"])
        try:
            make_strategy_config(base, options)
        except MatrixError as error:   # said of `base`: say it of this recipe's name
            message = str(error).removeprefix(f"strategies.{base}").lstrip(".: ")
            raise self.recipe.error(message + (f" (an option of {base})" if base != name else ""), where) from None
        return base, options

    def profile(self, name: str):
        from pilotlab.hardware import make_profile
        options = self.config.hardware.get(name)
        return make_profile(name, options.model_dump(exclude_none=True) if options else None)

    # evaluations ----------------------------------------------------------------------------------
    def offline(self, optimize: Job, combination: dict, hardware: str) -> Job:
        from pilotlab.hardware import host_fingerprint
        test = self.dataset(self.config.offline.data, ["offline", "data"])
        model, strategy = combination["model"], combination["strategy"]
        params = {"hardware": self.profile(hardware).as_dict(), "host": host_fingerprint(),
                  "timing": {"throughput_batch": self.config.offline.batch}}
        labels = {"model": model, "strategy": strategy, "hardware": hardware,
                  "test_set": self.config.offline.data}
        return Job("offline", f"offline {model}/{strategy} on {hardware}", params,
                   deps={"artifact": optimize, "test": tuple(test)}, labels=labels)

    def reference_jobs(self) -> list[Job]:
        return reference_jobs(self)


def _hardware_dependent(strategy: str) -> bool:
    from pilotlab.strategies import STRATEGIES
    return STRATEGIES.get(strategy).module in HARDWARE_DEPENDENT_STRATEGY_MODULES


def _check_model(recipe: Recipe, name: str, spec: ModelSpec) -> None:
    from pilotlab.models import make_config
    try:
        make_config(spec.arch, spec.options)
    except MatrixError as error:
        raise recipe.error(str(error), ["models", name]) from None


def online_jobs(planner: Planner, optimize: Job, combination: dict, hardware: str) -> list[Job]:
    model, strategy, circuit = combination["model"], combination["strategy"], str(combination["circuit"])
    labels = {"model": model, "strategy": strategy, "hardware": hardware}
    return [_lap(planner, f"online {model}/{strategy} on {hardware}", labels, hardware, circuit, direction,
                 {"brain": "network"}, {"artifact": optimize})
            for direction in planner.config.online.directions]


def reference_jobs(planner: Planner) -> list[Job]:
    """The explicit brain and the expert on every CPU profile and circuit the matrix drives (they
    use no GPU, so a CUDA profile adds nothing)."""
    cells = {(str(c.get("hardware", "cpu")), str(c["circuit"])) for c in planner.recipe.combinations
             if "circuit" in c and planner.profile(str(c.get("hardware", "cpu"))).device == "cpu"}
    return [_lap(planner, f"online {brain} on {hardware}", {"model": "reference", "strategy": brain,
                                                            "hardware": hardware},
                 hardware, circuit, direction, {"brain": brain}, {})
            for brain in planner.config.online.references for hardware, circuit in sorted(cells)
            for direction in planner.config.online.directions]


def _lap(planner: Planner, name: str, labels: dict, hardware: str, circuit: str, direction: str,
         brain: dict, deps: dict) -> Job:
    from pilotlab.hardware import host_fingerprint
    online = planner.config.online
    params, inputs = planner.circuit_param(circuit, ["matrix", "circuit"])
    params |= {**brain, "direction": direction, "hardware": planner.profile(hardware).as_dict(),
               "host": host_fingerprint(), "timing": online.timing, "control_hz": online.control_hz,
               "timeout_s": online.timeout_s, "repetitions": online.repetitions, "video": online.video}
    return Job("online", f"{name} at {circuit} {direction}", params, deps=deps, inputs=inputs,
               labels={**labels, "circuit": circuit, "direction": direction})


def plan(recipe: Recipe) -> list[Job]:
    return Planner(recipe).jobs()


def after_run(recipe: Recipe, summary, store) -> None:
    from pilotlab.report.recipe import report_after_run, report_folder
    written = report_after_run(recipe, summary, store)
    readme = report_folder(recipe) / "README.md"
    print(f"report: {readme} and index.html" if written else f"report unchanged: {readme}")


DOMAIN = Domain(
    name="pilotlab",
    sections=SECTIONS,
    axes={"model": _models, "strategy": _strategies, "hardware": _hardware, "circuit": _circuits},
    plan=plan,
    kind_modules=("pilotlab.jobs.record", "pilotlab.jobs.frames", "pilotlab.jobs.train",
                  "pilotlab.jobs.optimize", "pilotlab.jobs.offline", "pilotlab.jobs.online"),
    store_env="PILOTLAB_STORE",
    default_store=".pilotlab",
    after_run=after_run,
)
