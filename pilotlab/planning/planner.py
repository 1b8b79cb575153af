"""The planner: a validated recipe -> jobs, shared wherever their inputs are equal.

    record (per recording) -> frames (per recording) -> train (per model)
        [-> prepare (per model × preparation: a network pruned and fine-tuned once, for every strategy
            that converts it)]
        -> optimize (per model × strategy) -> timing (per model × strategy × hardware, fed training frames)
           -> offline (per model × strategy × hardware × test set: MSE, size, beside the timing's figures)
           -> online  (per model × strategy × hardware × circuit × direction: replaying the timing's latencies)
    plus reference laps (explicit brain, expert, the user's brains) per hardware × circuit × direction.

A combination may name a BehaviorMetrics `world` instead of a circuit (pilotlab.planning.worlds): its laps
are driven there, and a recorded offline test set is recorded there too; the network is timed once, whatever
its worlds and test set. The laps are planned in pilotlab.planning.laps. Relative paths in a recipe (bags,
dataset folders, circuit CSVs) are relative to the recipe's folder.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from matrix.errors import MatrixError, did_you_mean
from matrix.inputhash import hash_files
from matrix.jobs import InputFile, Job, Params, input_file
from matrix.recipe import Recipe
from pilotlab.errors import PilotlabError
from pilotlab.planning.checks import check_bag_topics, check_test_set
from pilotlab.planning.laps import check_tolerance_scope, online_jobs, reference_jobs
from pilotlab.planning.worlds import world_param
from pilotlab.recipe import DatasetSpec, ModelSpec, RecordingsSpec
from pilotlab.specs.base import Spec
from pilotlab.specs.frames import FramesSpec, PreprocessConfig
from pilotlab.specs.offline import OfflineSpec
from pilotlab.specs.optimize import OptimizeSpec
from pilotlab.specs.prepare import PrepareSpec
from pilotlab.specs.record import RecordSettings, RecordSpec
from pilotlab.specs.timing import TimingSpec


def job(kind: str, name: str, spec: Spec, **links) -> Job:
    """A job whose params are `spec`, every default written out (so the key says what ran)."""
    return Job(kind, name, spec.model_dump(mode="json"), **links)


# --- axes: which names a combination may carry -------------------------------------------------


class Planner:
    def __init__(self, recipe: Recipe):
        self.recipe, self.config = recipe, recipe.config
        self.folder = Path(recipe.file).resolve().parent
        self.datasets: dict[tuple[str, PreprocessConfig, str | None], list[Job]] = {}
        self.trained: dict[str, Job] = {}
        self.optimized: dict[tuple, Job] = {}
        self.shared_params: dict[tuple, Params] = {}
        self.once: dict[tuple, Any] = {}    # what planning works out once per name, not once per cell
        self.worlds_read: dict[str, tuple[dict, dict]] = {}     # pilotlab.planning.worlds.world_param

    def jobs(self) -> list[Job]:
        from pilotlab.definitions import check_definitions
        check_definitions(self)
        jobs: list[Job] = []
        for combination in self.recipe.combinations:
            jobs += self.combination_jobs(combination)
        jobs += self.reference_jobs()
        check_tolerance_scope(self)
        return jobs

    def combination_jobs(self, combination: dict[str, Any]) -> list[Job]:
        if "model" not in combination or "strategy" not in combination:
            missing = [axis for axis in ("model", "strategy") if axis not in combination]
            raise self.recipe.error(f"the combination {combination} has no {' and no '.join(missing)}; "
                                    "every combination needs a model and a strategy", ["matrix"])
        if "circuit" in combination and "world" in combination:
            raise self.recipe.error(f"the combination {combination} names a circuit and a world; a lap is driven on a "
                                    "circuit of pilotlab's own world or in a BehaviorMetrics world (which has its own "
                                    "circuit): use one axis per combination", ["matrix"])
        if "world" in combination:    # read (and checked) here, so an unknown world is the matrix's error
            world_param(self, str(combination["world"]), ["matrix", "world"])
        hardware = str(combination.get("hardware", "cpu"))
        optimize = self.optimize(str(combination["model"]), str(combination["strategy"]), hardware)
        timing = self.timing(optimize, str(combination["model"]), str(combination["strategy"]), hardware)
        jobs = [self.offline(optimize, timing, combination, hardware)]
        if "circuit" in combination or "world" in combination:
            jobs += online_jobs(self, optimize, combination, hardware, timing=timing)
        return jobs

    # datasets -----------------------------------------------------------------------------------
    def dataset(self, name: str, used_by: list, preprocess: PreprocessConfig | None = None,
                world: str | None = None) -> list[Job]:
        """The frames jobs of a dataset, preprocessed as `preprocess` says (default: pilotlab's); with
        `world`, a recorded dataset is recorded in that BM world instead (the same settings and seeds).
        A dataset is the set of its recordings: its jobs come in the order of their keys, so that the
        same recordings listed in another order are the same dataset (the same training; which recording
        is held out for validation is drawn by seed, pilotlab.data.split, not by the order)."""
        return self.remembered(("dataset", name, preprocess, world), lambda: self._dataset(name, used_by, preprocess, world))

    def _dataset(self, name: str, used_by: list, preprocess: PreprocessConfig | None, world: str | None) -> list[Job]:
        if name not in self.config.datasets:
            raise self.recipe.error(f"dataset {name!r} is not defined; datasets: "
                                    f"{', '.join(self.config.datasets) or '(none)'}", used_by)
        settings = preprocess or PreprocessConfig()
        spec = self.config.datasets[name]
        if world is not None and spec.record is not None:
            spec = spec.model_copy(update={"record": spec.record.model_copy(update={"circuits": [], "worlds": [world]})})
        else:
            world = None
        if (name, settings, world) not in self.datasets:
            self.datasets[name, settings, world] = self._dataset_jobs(name, spec, settings)
        return self.datasets[name, settings, world]

    def _dataset_jobs(self, name: str, spec: DatasetSpec, settings: PreprocessConfig) -> list[Job]:
        topics = {"image_topic": spec.topics.image, "command_topic": spec.topics.command,
                  **settings.model_dump(exclude={"version"})}
        shown = "" if settings == PreprocessConfig() else \
            f" ({settings.width}x{settings.height} {settings.interpolation}, rows {settings.crop_top}-{settings.crop_bottom})"
        # (no label in the params: renaming a dataset names its jobs anew, it does not rerun them)
        frames_spec, jobs = FramesSpec(**topics), []
        if spec.record is not None:
            for label, record in self._recordings(name, spec):
                jobs.append(job("frames", f"frames {label}{shown}", frames_spec,
                                deps={"bag": record}))
        for i, path in enumerate(spec.bags + spec.folders):
            where = ["datasets", name, "bags" if i < len(spec.bags) else "folders"]
            source = self.path(path, where, "recording")
            if i < len(spec.bags):
                self.remembered(("bag topics", name, str(source)),
                                lambda: check_bag_topics(self.recipe, name, spec, path, source, i))
            label = f"{name}/{Path(path).name}"
            jobs.append(job("frames", f"frames {label}{shown}", frames_spec,
                            inputs={"bag": self._recording_input(source, where)}))
        return sorted(jobs, key=lambda frames: frames.key)

    def _recording_input(self, source: Path, where: list) -> InputFile:
        """A bag is hashed whole; a DeepLearningStudio folder by what reading it reads (data.csv and the
        images its rows name), so a file added beside them reruns nothing."""
        from pilotlab.data.folder_rows import is_dataset_folder, read_files
        if not is_dataset_folder(source):
            return input_file(str(source))
        try:
            return InputFile(str(source), hash_files(source, read_files(source)))
        except MatrixError as error:
            raise self.recipe.error(str(error), where) from None

    def _recordings(self, name: str, spec: DatasetSpec) -> list[tuple[str, Job]]:
        """(label, record job) for every circuit and direction of the dataset."""
        record: RecordingsSpec = spec.record
        settings = {field: getattr(record, field) for field in RecordSettings.model_fields}
        jobs = []
        places = [(circuit, self.circuit_param(circuit, ["datasets", name, "record", "circuits"]))
                  for circuit in record.circuits]
        # a BM world of a circuit's name (simple_circuit, many_curves) recorded beside it: named apart
        places += [(f"{world} (BM world)" if world in record.circuits else world,
                    world_param(self, world, ["datasets", name, "record", "worlds", i]))
                   for i, world in enumerate(record.worlds)]
        for place, (params, inputs) in places:
            for direction in record.directions:
                label = f"{name}/{place} {direction}"
                jobs.append((label, job("record", f"record {label}", RecordSpec(
                    **settings, **params, direction=direction), inputs=inputs)))
        return jobs

    def circuit_param(self, circuit: str, where: list) -> tuple[dict, dict]:
        """(params, inputs) naming a circuit: a recipe-defined CSV is an input file (content hashed)."""
        return self.remembered(("circuit", circuit), lambda: self._circuit_param(circuit, where))

    def _circuit_param(self, circuit: str, where: list) -> tuple[dict, dict]:
        """A built-in circuit by name; a CSV by its content (the input's hash) and its file's stem, so the
        same file named two ways is one job and a moved project reruns nothing (the job reads the input's path)."""
        if circuit in self.config.circuits:
            csv = self.path(self.config.circuits[circuit].csv, ["circuits", circuit, "csv"], "file")
        else:
            from pilotlab.circuits import csv_path_of
            from pilotlab.circuits.lookup import missing_csv
            if problem := missing_csv(circuit, self.folder):
                raise self.recipe.error(problem, where)
            try:
                found = csv_path_of(circuit, self.folder)
            except MatrixError as error:
                raise self.recipe.error(str(error), where) from None
            if found is None:   # built in
                return {"circuit": circuit}, {}
            csv = self.path(str(found.resolve()), where, "file")
        inputs = {"circuit_csv": input_file(str(csv))}   # hashed first: hashing bounds what may be read
        from pilotlab.circuits.load import get_circuit
        try:
            get_circuit(str(csv))   # a CSV that is no lap is this recipe's error now, not a failed record job later
        except MatrixError as error:
            raise self.recipe.error(str(error), where) from None
        return {"circuit": csv.stem}, inputs

    def path(self, value: str, where: list, expect: str = "any") -> Path:
        """The path a recipe value names (relative to the recipe's folder); it must exist, and be what
        `expect` says ("file", "recording": see pilotlab.definitions.path_problem), checked before hashing."""
        from matrix.inputhash import shown_path, system_root
        from pilotlab.definitions import path_problem
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
        if root := system_root(path.resolve()):   # said here, with the recipe's file, line and key
            raise self.recipe.error(f"{shown_path(Path(value))} is a system file (below {root}), not data", where)
        if problem := path_problem(path, expect):
            raise self.recipe.error(f"{shown_path(Path(value))} {problem}", where)
        return path

    # models and strategies ------------------------------------------------------------------------
    def train(self, model: str) -> Job:
        from pilotlab.definitions import check_arch
        if model not in self.trained:
            spec: ModelSpec = self.config.models[model]
            frames = self.dataset(spec.data, ["models", model, "data"], spec.preprocess)
            check_arch(self.recipe, model, spec)
            params = spec.model_dump(mode="json", exclude={"data"})
            self.trained[model] = Job("train", f"train {model}", params, deps={"frames": tuple(frames)},
                                      inputs=model_inputs(self, model, spec))
        return self.trained[model]

    def optimize(self, model: str, strategy: str, hardware: str) -> Job:
        return self.remembered(("optimize", model, strategy, hardware), lambda: self._optimize(model, strategy, hardware))

    def _optimize(self, model: str, strategy: str, hardware: str) -> Job:
        from pilotlab.strategies import STRATEGIES
        base, options = self.strategy(strategy)
        device = self.profile(hardware).device if STRATEGIES.get(base).hardware_dependent else None
        if (model, strategy, device) not in self.optimized:
            train = self.train(model)
            suffix = f" for {device}" if device else ""
            params = self.params_once(("optimize", strategy, device), lambda: optimize_spec(base, options, device))
            deps = {"model": train, "calibration": train.deps["frames"]}
            if prepared := self.prepared(model, strategy):
                deps["prepared"] = prepared
            self.optimized[model, strategy, device] = Job(
                "optimize", f"optimize {model}/{strategy}{suffix}", params, deps=deps)
        return self.optimized[model, strategy, device]

    def prepared(self, model: str, strategy: str) -> Job | None:
        """The prepare job of the network recipe strategy `strategy` converts, one per model and preparation
        options, whichever strategies share it (pilotlab.strategies.configs.prepare); None for a strategy
        that prepares none, or whose packages are missing here (it is not applicable: nothing to prepare)."""
        found = self.remembered(("prepare spec", strategy), lambda: self._prepare_spec(strategy))
        if found is None:
            return None
        spec, text = found
        return self.remembered(("prepare", model, text), lambda: self._prepare(model, spec))

    def _prepare_spec(self, strategy: str) -> tuple[PrepareSpec, str] | None:
        """The preparation of a recipe strategy and its JSON (the same for every model: made once per strategy)."""
        from pilotlab.strategies import STRATEGIES, make_strategy_config, preparation_for
        base, options = self.strategy(strategy)
        if not STRATEGIES.get(base).prepared_by or STRATEGIES.get(base).missing:
            return None
        entry, config = preparation_for(base, make_strategy_config(base, options))
        spec = PrepareSpec(preparation=entry.name, options=entry.options_of(config))
        return spec, spec.model_dump_json()

    def _prepare(self, model: str, spec: PrepareSpec) -> Job:
        """Named by its options that differ from the preparation's defaults: "prepare pilotnet/channel_pruning
        (amount 0.65, finetune_epochs 12, distill 0.5)"."""
        from pilotlab.strategies import PREPARATIONS
        entry, train = PREPARATIONS.get(spec.preparation), self.train(model)
        defaults = entry.defaults
        shown = ", ".join(f"{name} {value:g}" for name, value in spec.options.items() if value != defaults.get(name))
        return job("prepare", f"prepare {model}/{spec.preparation}" + (f" ({shown})" if shown else ""), spec,
                   deps={"model": train, "calibration": train.deps["frames"]})

    def strategy(self, name: str) -> tuple[str, dict[str, Any]]:
        """(registered strategy, its full options) for a strategy name of the recipe (aliases via `use:`)."""
        return self.remembered(("strategy", name), lambda: self._strategy(name))

    def _strategy(self, name: str) -> tuple[str, dict[str, Any]]:
        from pilotlab.strategies import STRATEGIES, full_options
        options = dict(self.config.strategies.get(name, {}))
        base = options.pop("use", name)
        where = ["strategies", name]
        if not isinstance(base, str):
            kind = {list: "a list", dict: "a mapping", type(None): "nothing"}.get(type(base), type(base).__name__)
            raise self.recipe.error(f"`use` names one strategy (got {kind}); e.g. use: local_prune", where + ["use"])
        if "use" not in self.config.strategies.get(name, {}) and name not in STRATEGIES:
            raise self.recipe.error(f"{name!r} is not a built-in strategy{did_you_mean(name, STRATEGIES.names())}; a "
                                    f"strategy of your own names the one it varies: {name}: {{use: local_prune, ...}}",
                                    where)
        if base not in STRATEGIES and base in self.config.strategies:
            raise self.recipe.error(f"`use` names a built-in strategy, and {base!r} is a variant of this recipe; "
                                    f"name the strategy {base!r} uses, with the options you want", where + ["use"])
        if base not in STRATEGIES:
            raise self.recipe.error(f"unknown strategy {base!r}{did_you_mean(base, STRATEGIES.names())}; "
                                    f"known: {', '.join(sorted(STRATEGIES.names()))}", where + ["use"])
        if base != name and name in STRATEGIES:
            raise self.recipe.error(f"{name!r} is a built-in strategy; give the variant of {base} a new name",
                                    where + ["use"])
        if "version" in options:     # the code's own (what the job key follows); a checkpoint keeps its own
            raise self.recipe.error("version is not an option: it is the strategy code's own", where + ["version"])
        try:
            return base, full_options(base, options)
        except MatrixError as error:   # said of `base`: say it of this recipe's name
            message = str(error).removeprefix(f"strategies.{base}").lstrip(".: ")
            raise self.recipe.error(message + (f" ({name} uses {base})" if base != name else ""), where) from None

    def profile(self, name: str):
        from pilotlab.hardware import recipe_profile
        options = self.config.hardware.get(name)
        return self.remembered(("profile", name), lambda: recipe_profile(
            name, options.model_dump(exclude_none=True, exclude={"latency_file"}) if options else None))

    def latency_file(self, hardware: str) -> Path | None:
        """The device's latency file a hardware profile names (replayed in its laps), if any."""
        options = self.config.hardware.get(hardware)
        if options is None or options.latency_file is None:
            return None
        return self.remembered(("latency_file", hardware), lambda: self.path(
            options.latency_file, ["hardware", hardware, "latency_file"], "file"))

    def check_latency_file(self, hardware: str, model: str | None = None, strategy: str | None = None) -> None:
        """The hardware profile's latency file reads as one (every latency_ms a number of milliseconds in
        range), with rows a lap of `model`/`strategy` can replay: told here, with the recipe's file, line
        and key, rather than by the lap after the offline jobs ran."""
        from pilotlab.online.latency import latency_file_samples, read_latency_file
        where = ["hardware", hardware, "latency_file"]
        path = self.latency_file(hardware)
        try:
            rows = self.remembered(("latency_rows", hardware), lambda: read_latency_file(path))
            if strategy is not None:
                latency_file_samples(path, model, strategy, rows)
        except PilotlabError as error:
            raise self.recipe.error(str(error), where) from None

    # evaluations ----------------------------------------------------------------------------------
    def timing(self, optimize: Job, model: str, strategy: str, hardware: str) -> Job:
        """The timing job of a (model, strategy, hardware): fed the training frames its optimize job was made
        from, never the test set, so editing what only the MSE reads re-times nothing (nor reruns a lap)."""
        return self.remembered(("timing", model, strategy, hardware),
                               lambda: self._timing(optimize, model, strategy, hardware))

    def _timing(self, optimize: Job, model: str, strategy: str, hardware: str) -> Job:
        profile = self.profile(hardware)
        params = self.params_once(("timing", hardware), lambda: TimingSpec(
            hardware=profile.as_dict(), host=profile.host, batch=self.config.offline.batch).model_dump(mode="json"))
        return Job("timing", f"timing {model}/{strategy} on {hardware}", params,
                   deps={"artifact": optimize, "frames": optimize.deps["calibration"]},
                   labels={"model": model, "strategy": strategy, "hardware": hardware})

    def offline(self, optimize: Job, timing: Job, combination: dict, hardware: str) -> Job:
        """The offline job of a combination: one per (model, strategy, hardware, world), whatever the circuit."""
        model, strategy, world = combination["model"], combination["strategy"], combination.get("world")
        return self.remembered(("offline", model, strategy, hardware, world),
                               lambda: self._offline(optimize, timing, model, strategy, world, hardware))

    def _offline(self, optimize: Job, timing: Job, model: str, strategy: str, world: Any, hardware: str) -> Job:
        self.remembered(("test set",), lambda: check_test_set(self.recipe, self.config))
        test = self.dataset(self.config.offline.data, ["offline", "data"], self.config.models[model].preprocess,
                            world=None if world is None else str(world))
        labels = {"model": model, "strategy": strategy, "hardware": hardware,
                  "test_set": self.config.offline.data}
        in_world = world is not None and self.config.datasets[self.config.offline.data].record is not None
        if in_world:
            labels |= {"test_set": f"{self.config.offline.data} in {world}", "world": str(world)}
        profile = self.profile(hardware)
        params = self.params_once(("offline", hardware), lambda: OfflineSpec(
            hardware=profile.as_dict(), host=profile.host).model_dump(mode="json"))
        return Job("offline", f"offline {model}/{strategy} on {hardware}{f' in {world}' if in_world else ''}", params,
                   deps={"artifact": optimize, "test": tuple(test), "timing": timing}, labels=labels)

    def reference_jobs(self) -> list[Job]:
        return reference_jobs(self)

    def params_once(self, slot: tuple, build) -> Params:
        """Job params shared by many jobs (every strategy's laps on one circuit), validated and written once."""
        if slot not in self.shared_params:
            self.shared_params[slot] = Params(build())
        return self.shared_params[slot]

    def remembered(self, slot: tuple, build):
        """What `build` gives for `slot`, worked out once per plan (a failure is raised each time)."""
        if slot not in self.once:
            self.once[slot] = build()
        return self.once[slot]


def optimize_spec(strategy: str, options: dict[str, Any], device: str | None) -> dict[str, Any]:
    """An optimize job's params; a strategy whose result depends on the hardware is made for one device, here."""
    if device is None:
        return OptimizeSpec(strategy=strategy, options=options).model_dump(mode="json")
    from pilotlab.hardware import host_fingerprint
    return OptimizeSpec(strategy=strategy, options=options, host=host_fingerprint(),
                        hardware={"name": device, "device": device, "threads": None}).model_dump(mode="json")


def model_inputs(planner: Planner, name: str, spec: ModelSpec) -> dict[str, InputFile]:
    """The files a model is made from, content-hashed into its train job's key: the network's source
    (the file and the user's modules it imports), the weights, the TorchScript or ONNX file.
    Planning reads them; it never runs them (a syntax error is reported here, with its line)."""
    from pilotlab import usercode
    inputs = {}
    for key in ("weights", "torchscript", "onnx"):
        if getattr(spec, key) is not None:
            inputs[key] = input_file(str(planner.path(getattr(spec, key), ["models", name, key], "file")))
    if spec.onnx is not None:   # its weights kept in files beside it ("external data") are inputs too
        from pilotlab.models.onnx_data import planned_data_files
        try:
            data = planned_data_files(Path(inputs["onnx"].path))
        except MatrixError as error:
            raise planner.recipe.error(str(error), ["models", name, "onnx"]) from None
        inputs.update({f"onnx data {location}": input_file(str(file)) for location, file in data.items()})
    if spec.network is not None:
        try:
            usercode.check_source(spec.network, planner.folder, spec.options)
            inputs["network_source"] = usercode.source_input(spec.network, planner.folder)
        except MatrixError as error:
            raise planner.recipe.error(str(error), ["models", name, "network"]) from None
    return inputs


def plan(recipe: Recipe) -> list[Job]:
    return Planner(recipe).jobs()
