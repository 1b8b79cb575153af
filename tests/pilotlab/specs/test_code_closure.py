"""Every job kind's key follows the code its handler can run: the import closure of the handler's
module, read here independently of pilotlab's fingerprinting, is covered module by module."""
import ast
import contextlib
import functools
import importlib.util
from pathlib import Path

import pytest

import matrix.fingerprint as fingerprint
from matrix import engine
from matrix.kinds import KINDS
from matrix.recipe import load_recipe
from pilotlab.domain import DOMAIN
from pilotlab.strategies import STRATEGIES

ROOT = Path(__file__).resolve().parents[3]
RECIPE = """
name: closure
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.2}}
  test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 2}}
models:
  pilotnet: {arch: pilotnet, epochs: 1}
  stacked: {arch: pilotnet_stacked, options: {frames: 2}, epochs: 1}
matrix:
  model: [pilotnet, stacked]
  strategy: [%s]
  hardware: [cpu, cuda]
  circuit: [simple_circuit]
"""


@functools.cache
def imports_of(module: str) -> set[str]:
    """The pilotlab modules `module` names in any import statement (inside functions too)."""
    origin = Path(importlib.util.find_spec(module).origin)
    package = module if origin.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(origin.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        found |= {n for n in names if n.startswith("pilotlab.") and is_module(n)}
    return found


def is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:   # `from pilotlab.errors import PilotlabError`: a name, not a module
        return False


def reachable(start: str, stop: set[str] = frozenset()) -> set[str]:
    seen, pending = set(), [start]
    while pending:
        module = pending.pop()
        if module not in seen and module not in stop:
            seen.add(module)
            pending += imports_of(module)
    return seen


def code_of(job) -> str:
    """The job's code fingerprint, from the modules its kind names (the per-kind cache bypassed, so
    an edit shows at once)."""
    kind = KINDS.get(job.kind)
    extra = tuple(kind.code_for(job.params)) if kind.code_for else ()
    return fingerprint.closure_fingerprint(kind.base_modules() + extra, kind.code)


@contextlib.contextmanager
def edited(module: str):
    """As if `module`'s file had been edited: its remembered hash differs, derived facts are stale."""
    ident = f"{module}#own"
    fingerprint._own_source_hash(module)
    original = fingerprint._SOURCE_HASHES[ident]
    fingerprint._SOURCE_HASHES[ident] = "edited"
    try:
        yield
    finally:
        fingerprint._SOURCE_HASHES[ident] = original


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    recipe = tmp_path_factory.mktemp("closure") / "closure.yaml"
    recipe.write_text(RECIPE % ", ".join(STRATEGIES.names()))
    return engine.plan_jobs(load_recipe(recipe, DOMAIN), DOMAIN)


def expected_modules(job) -> set[str]:
    """What the job runs: its handler's closure, its params model's, and (optimize) its own
    strategy's, the other strategies' modules being the only ones a kind may leave out."""
    kind = KINDS.get(job.kind)
    own, others = set(), set()
    if job.kind == "optimize":   # the handler is named by string in its registration, not imported
        own = set().union(*map(reachable, STRATEGIES.get(job.params["strategy"]).modules))
        others = {module for _, entry in STRATEGIES.items() for module in entry.modules} - own
    modules = reachable(kind.module, others) | reachable(kind.params.__module__, others) | own
    if job.kind == "train":   # the network class is named by string in its config, not imported
        from pilotlab.models import MODELS
        modules |= reachable(MODELS.get(job.params["arch"]).network_module)
    return modules


def test_every_module_a_handler_can_run_is_in_its_jobs_key(jobs):
    checked = set()
    for job in {(job.kind, job.params.get("strategy"), job.params.get("arch")): job for job in jobs}.values():
        before = code_of(job)
        for module in sorted(expected_modules(job)):
            with edited(module):
                assert code_of(job) != before, f"editing {module} would not change the key of {job.name}"
            checked.add(module)
    assert {"pilotlab.hardware", "pilotlab.offline", "pilotlab.timing", "pilotlab.specs.timing", "pilotlab.online.drive", "pilotlab.training",
            "pilotlab.data.bags", "pilotlab.strategies.prune"} <= checked


def test_editing_one_strategy_leaves_the_others_alone(jobs):
    optimize = {job.params["strategy"]: job for job in jobs if job.kind == "optimize"}
    before = {name: code_of(job) for name, job in optimize.items()}
    with edited("pilotlab.strategies.cluster"):
        changed = {name for name, job in optimize.items() if code_of(job) != before[name]}
    assert changed == {"cluster"}


def test_editing_how_timings_are_taken_makes_every_timing_job_stale(jobs):
    before = {job.name: code_of(job) for job in jobs}
    with edited("pilotlab.hardware"):
        changed = {job.name for job in jobs if code_of(job) != before[job.name]}
    timing = {job.name for job in jobs if job.kind in ("timing", "offline", "online")}
    assert timing and timing <= changed and any(job.kind == "timing" for job in jobs)
    assert not any(name.startswith(("record", "frames", "train")) for name in changed)


def test_a_timing_job_runs_the_timing_code_and_no_lap_or_training(jobs):
    modules = set(KINDS.get("timing").base_modules())
    assert {"pilotlab.jobs.timing", "pilotlab.specs.timing", "pilotlab.offline", "pilotlab.timing",
            "pilotlab.predictor", "pilotlab.data.frames"} <= modules
    assert not modules & {"pilotlab.jobs.offline", "pilotlab.online.drive", "pilotlab.training"}


def test_editing_a_guess_re_keys_no_job_and_every_kind_has_one(jobs):
    """What a job typically takes (pilotlab.specs.guesses) is the scheduler's first guess, never a job's
    code: the lap cell's guess, written in the online kind's module, made every lap stale when tuned."""
    from pilotlab.specs import KIND_MODULES
    before = {job.name: code_of(job) for job in jobs}
    with edited("pilotlab.specs.guesses"):
        assert [job.name for job in jobs if code_of(job) != before[job.name]] == []
    kinds = {job.kind for job in jobs}
    assert {"record", "frames", "train", "optimize", "timing", "offline", "online"} <= kinds
    assert all(KINDS.get(kind).typical_s or KINDS.get(kind).typical_for for kind in KINDS
               if KINDS.get(kind).module.startswith("pilotlab.")), "a kind of pilotlab's without a guess"
    assert KIND_MODULES[-1] == "pilotlab.specs.guesses"   # imported where the kinds are, after them
