"""The closed-loop laps of a plan: each combination's laps (on its circuit, or in its BM world) in every
direction, replaying the latencies of its timing job (or a device's latency file), and the reference
brains' laps on the CPU profiles (reference_cells) and places the matrix drives.

With a tolerance search, a brain's laps on longer circuits start their search at the tolerance its lap
on the shortest circuit found (a `tolerance_hint` dependency: same brain, hardware and direction; the
shortest by BehaviorMetrics' timeouts, lap_scale). The study's Montreal cells found theirs within 10 ms
of simple_circuit's in 22 of 24, so each drives two laps of its search where the bisection drove three to
four (pilotlab.online.tolerance). BM worlds take no hint: another camera and world, another tolerance."""
from __future__ import annotations

from typing import Any

from matrix.errors import MatrixError, did_you_mean
from matrix.jobs import Job, Params, input_file
from pilotlab.circuits.registry import lap_scale
from pilotlab.planning.worlds import world_param
from pilotlab.specs.online import LapSettings, OnlineSpec, timed_live


def online_jobs(planner, optimize: Job, combination: dict, hardware: str, timing: Job) -> list[Job]:
    model, strategy, place = combination["model"], combination["strategy"], lap_place(combination)
    labels = {"model": model, "strategy": strategy, "hardware": hardware}
    # the same for every circuit and world of a (model, strategy, hardware): worked out once
    brain, deps, inputs = planner.remembered(("replay", model, strategy, hardware),
                                             lambda: replay_inputs(planner, combination, hardware, timing))
    name, deps = f"online {model}/{strategy} on {hardware}", {"artifact": optimize, **deps}
    return [_hinted_lap(planner, ("network", model, strategy, hardware), name, labels, hardware, place, direction,
                        brain, deps, inputs) for direction in planner.config.online.directions]


def _hinted_lap(planner, brain_key: tuple, name: str, labels: dict, hardware: str, place: tuple[str, str],
                direction: str, brain: dict, deps: dict, inputs: dict | None = None) -> Job:
    """The lap, built once per plan; a searched lap on a circuit longer than the brain's shortest searched
    one, with the lap there as its `tolerance_hint` (see the module docstring)."""
    def build() -> Job:
        searched = is_searched(planner, {**labels, place[0]: place[1], "direction": direction})
        scout = scout_circuit(planner, brain_key, labels, direction) if searched else None
        hint = {}
        if scout is not None and place[0] == "circuit" and place[1] != scout:
            hint = {"tolerance_hint": _hinted_lap(planner, brain_key, name, labels, hardware, ("circuit", scout),
                                                  direction, brain, deps, inputs)}
        return _lap(planner, name, labels, hardware, place, direction, brain, {**deps, **hint}, inputs, searched)
    return planner.remembered(("lap", brain_key, place, direction), build)


def is_searched(planner, cell: dict[str, str]) -> bool:
    """Whether the lap cell ({axis: name}) has a tolerance search: the recipe has one, and `only` (if
    given) names the cell. Remembers the cells' names and which `only` entries named one
    (check_tolerance_scope)."""
    tolerance = tolerance_scope(planner)
    if tolerance is None:
        return False
    seen = planner.remembered(("lap cell names",), dict)
    for axis, name in cell.items():
        seen.setdefault(axis, set()).add(name)
    matched = tolerance.matches(cell)
    planner.remembered(("tolerance entries matched",), set).update(matched)
    return bool(matched)


def tolerance_scope(planner):
    """The recipe's tolerance search with `only`'s model and strategy names as the plan names their laps:
    a name with the same definition as another is planned as the first of them (matrix.grid)."""
    def canonical():
        tolerance = planner.config.online.tolerance
        if tolerance is None or tolerance.only is None:
            return tolerance
        members = planner.recipe.grid.members
        first = {value: values[0] for axis in ("model", "strategy") for values in members.get(axis, ())
                 for value in values}
        only = [{axis: [first.get(name, name) if axis in ("model", "strategy") else name for name in names]
                 for axis, names in entry.items()} for entry in tolerance.only]
        return tolerance.model_copy(update={"only": only})
    return planner.remembered(("tolerance scope",), canonical)


def check_tolerance_scope(planner) -> None:
    """Each name in `online.tolerance.only` is one a lap of the matrix has, and each entry names some lap
    cell, else a recipe error at it (a misspelt name would leave the cells it meant unsearched without a
    word)."""
    tolerance = tolerance_scope(planner)
    if tolerance is None or tolerance.only is None:
        return
    seen = planner.remembered(("lap cell names",), dict)
    matched = planner.remembered(("tolerance entries matched",), set)
    for i, (entry, given) in enumerate(zip(tolerance.only, planner.config.online.tolerance.only)):
        for axis, names in entry.items():
            for name, said in zip(names, given[axis]):
                if name not in seen.get(axis, ()):
                    known = sorted(seen.get(axis, ()))
                    raise planner.recipe.error(
                        f"{axis} {said!r} names no lap of the matrix{did_you_mean(said, known)}; its laps' {axis} "
                        f"names: {', '.join(known) or 'none'}{_naming_hint(axis, seen)}",
                        ["online", "tolerance", "only", i, axis])
        if i not in matched:
            said = ", ".join(f"{axis}: {'|'.join(names)}" for axis, names in given.items())
            raise planner.recipe.error(f"{{{said}}} names no lap cell of the matrix (no lap has all of it); name "
                                       "cells the matrix drives (the reference brains are model `reference`, driven "
                                       "on the first CPU profile of each circuit when their laps are replayed)",
                                       ["online", "tolerance", "only", i])


def _naming_hint(axis: str, seen: dict) -> str:
    """Where a name is on another axis than the user looked."""
    if axis == "circuit" and seen.get("world"):
        return "; laps in a BehaviorMetrics world are named by `world`"
    if axis == "model":
        return "; the reference brains are model `reference`"
    return ""


def scout_circuit(planner, brain_key: tuple, labels: dict, direction: str) -> str | None:
    """The shortest circuit on which a brain (("network", model, strategy, hardware), or ("reference", name,
    hardware)) has a searched lap in `direction`, when it laps more than one circuit; else None."""
    circuits = planner.remembered(("scouts",), lambda: _scouts(planner)).get(brain_key, [])
    searched = [circuit for circuit in circuits if is_searched(planner, {**labels, "circuit": circuit,
                                                                         "direction": direction})]
    return searched[0] if len(searched) > 1 else None


def _scouts(planner) -> dict[tuple, list[str]]:
    """Each brain's circuits, shortest first (by BehaviorMetrics' timeouts, lap_scale), where it laps more
    than one."""
    circuits: dict[tuple, set[str]] = {}
    for combination in planner.recipe.combinations:
        # one without a model or strategy is refused, with its message, when the planner comes to it
        if "circuit" in combination and "model" in combination and "strategy" in combination:
            brain_key = ("network", str(combination["model"]), str(combination["strategy"]),
                         str(combination.get("hardware", "cpu")))
            circuits.setdefault(brain_key, set()).add(str(combination["circuit"]))
    for hardware, place in reference_cells(planner):
        if place[0] == "circuit":
            for reference in planner.config.online.references:
                circuits.setdefault(("reference", reference_name(reference), hardware), set()).add(place[1])
    return {key: sorted(names, key=lambda circuit: (lap_scale(circuit), circuit))
            for key, names in circuits.items() if len(names) > 1}


def lap_place(combination: dict) -> tuple[str, str]:
    """("circuit", name) or ("world", name): where a combination's laps are driven."""
    return ("world", str(combination["world"])) if "world" in combination else ("circuit", str(combination["circuit"]))


def replay_inputs(planner, combination: dict, hardware: str, timing: Job) -> tuple[dict, dict, dict]:
    """(params, deps, inputs) of a network lap for the latencies it replays: the timing job's samples
    (and the baseline's timing job's, to scale them to latency_scale_to_ms), or the hardware profile's
    latency file; never an offline job's, so the test set is none of a lap's business.
    (Shared by the laps of every circuit and world: read-only.)"""
    online, model = planner.config.online, str(combination["model"])
    params: dict[str, Any] = {"brain": "network"}
    if online.timing != "replay":
        return params, {}, {}
    latency_file = planner.latency_file(hardware)
    if latency_file is not None:
        planner.check_latency_file(hardware, model, str(combination["strategy"]))
        if online.latency_scale_to_ms is not None:   # the baseline's rows set the scale
            planner.check_latency_file(hardware, model, "baseline")
        params["latency_for"] = {"model": model, "strategy": str(combination["strategy"])}
        return params, {}, {"latency_file": input_file(str(latency_file))}
    deps: dict[str, Job] = {"timing": timing}
    if online.latency_scale_to_ms is not None:
        deps["scale_reference"] = planner.timing(planner.optimize(model, "baseline", hardware), model, "baseline",
                                                 hardware)
    return params, deps, {}


def reference_jobs(planner) -> list[Job]:
    """The reference brains (explicit, expert, the user's) on the CPU profiles (reference_cells) and circuits
    the matrix drives (they use no GPU, so a CUDA profile adds nothing)."""
    jobs = []
    for index, reference in enumerate(planner.config.online.references):
        name, brain, inputs = reference_brain(planner, reference, index)
        jobs += [_hinted_lap(planner, ("reference", name, hardware), f"online {name} on {hardware}",
                             {"model": "reference", "strategy": name, "hardware": hardware},
                             hardware, place, direction, brain, {}, inputs)
                 for hardware, place in reference_cells(planner) for direction in planner.config.online.directions]
    return jobs


def reference_cells(planner) -> list[tuple[str, tuple[str, str]]]:
    """(hardware, place) of the reference laps, sorted. Replayed or lockstep, a reference brain is charged
    no latency and its lap does not depend on the CPU profile: each place is driven on its first CPU
    profile alone (a recipe with cpu and cpu1 drove the explicit and expert brains twice, to the same
    results). Timed on this host's clock (measured, realtime), on every CPU profile the matrix drives there."""
    def cells():
        driven = {(str(c.get("hardware", "cpu")), lap_place(c)) for c in planner.recipe.combinations
                  if "circuit" in c or "world" in c}
        on_cpu = sorted((hardware, place) for hardware, place in driven if planner.profile(hardware).device == "cpu")
        if timed_live({"timing": planner.config.online.timing}):
            return on_cpu
        first = {place: hardware for hardware, place in reversed(on_cpu)}
        return sorted((hardware, place) for place, hardware in first.items())
    return planner.remembered(("reference cells",), cells)


def reference_name(reference: str | dict[str, str]) -> str:
    """A reference's row name: a built-in brain's name, or the key of {name: file.py:Class}."""
    if isinstance(reference, str):
        return reference
    (name, _), = reference.items()
    return name


def reference_brain(planner, reference: str | dict[str, str], index: int) -> tuple[str, dict, dict]:
    """(row name, the online job's brain params, its input files) of a reference: a built-in brain's
    name, or {name: file.py:Class} for a brain the user wrote (its source hash goes into the key;
    planning reads the files, never runs them)."""
    name = reference_name(reference)
    if isinstance(reference, str):
        return name, {"brain": reference}, {}
    from pilotlab import usercode
    spec = reference[name]
    try:
        usercode.check_source(spec, planner.folder)
        source = usercode.source_input(spec, planner.folder)
    except MatrixError as error:
        raise planner.recipe.error(str(error), ["online", "references", index, name]) from None
    # the recipe's folder is not in the key (the lap finds it from its input): a moved project keeps its laps
    brain = {"brain": "user", "user_brain": {"name": name, "spec": spec}}
    return name, brain, {"brain_source": source}


def _lap(planner, name: str, labels: dict, hardware: str, place: tuple[str, str], direction: str,
         brain: dict, deps: dict, inputs: dict | None, searched: bool) -> Job:
    axis, circuit = place
    # The params of every lap of one (hardware, place, direction, brain, search) are equal: built once.
    slot = ("online", hardware, axis, circuit, direction, _brain_slot(brain), searched)
    params, circuit_inputs, place_labels = planner.remembered(slot, lambda: _lap_params(
        planner, hardware, axis, circuit, direction, brain, searched))
    return Job("online", f"{name} at {circuit} {direction}", params, deps=deps,
               inputs={**circuit_inputs, **inputs} if inputs else circuit_inputs, labels={**labels, **place_labels})


def _brain_slot(brain: dict) -> str:
    """The brain's part of a lap's params slot: its name alone for a plain brain (most laps: a network
    replaying its timing job's latencies), else every setting written out (never starts like a name)."""
    if brain.keys() == {"brain"}:
        return brain["brain"]
    return repr(sorted(brain.items()))


def _lap_params(planner, hardware: str, axis: str, circuit: str, direction: str, brain: dict,
                searched: bool) -> tuple:
    """(params, inputs, labels) every lap of one hardware, place, direction, brain and search shares."""
    if axis == "world":
        params, circuit_inputs = world_param(planner, circuit, ["matrix", "world"])
        labels = {"world": circuit}
    else:
        params, circuit_inputs = planner.circuit_param(circuit, ["matrix", "circuit"])
        labels = {}
    online = planner.config.online
    settings = {field: getattr(online, field) for field in LapSettings.model_fields}
    settings["tolerance"] = online.tolerance.search if searched else None
    profile = planner.profile(hardware)
    spec = OnlineSpec(**settings, **params, **brain, direction=direction, host=profile.host, hardware=profile.as_dict())
    return Params(spec.model_dump(mode="json")), circuit_inputs, {**labels, "circuit": circuit, "direction": direction}
