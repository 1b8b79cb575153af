"""The driving domain's planner: recipes -> jobs shared wherever inputs are equal; recipe errors."""
import math
import time
from collections import Counter
from pathlib import Path

import pytest

from matrix import RecipeError, engine
from matrix.errors import MatrixError
from matrix.kinds import KINDS
from matrix.recipe import load_recipe
from pilotlab.domain import DOMAIN
from tests.pilotlab.tracks import stadium

ROOT = Path(__file__).resolve().parents[2]

RECIPE = """\
name: plan-test
datasets:
  train: {record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 0.2}}
  test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 3}}
models:
  small: {epochs: 1}
  other: {epochs: 2}
strategies:
  local_prune: {finetune_epochs: 1}
  prune_more: {use: local_prune, conv: 0.5}
matrix:
  model: [small, other]
  strategy: [baseline, local_prune, prune_more]
  hardware: [cpu, cpu1]
  circuit: [simple_circuit]
"""


def recipe_at(tmp_path: Path, text: str = RECIPE):
    path = tmp_path / "recipe.yaml"
    path.write_text(text)
    return load_recipe(path, DOMAIN)


def kinds(jobs) -> Counter:
    return Counter(job.kind for job in jobs)


def test_jobs_are_shared_wherever_inputs_are_equal(tmp_path):
    jobs = engine.plan_jobs(recipe_at(tmp_path), DOMAIN)
    assert kinds(jobs) == {
        "record": 3, "frames": 3,        # two training recordings, one test recording
        "train": 2,                      # one per model
        "optimize": 2 * 3,               # per (model, strategy)
        "prepare": 2 * 2,                # per model and l1_pruning options: local_prune's, prune_more's
        "timing": 2 * 3 * 2,             # per (model, strategy, hardware)
        "offline": 2 * 3 * 2,            # per (model, strategy, hardware) and test set
        # per cell and direction, plus explicit + expert once: replayed, a reference lap is the same on any
        # CPU profile (outside test: driven on cpu and cpu1, to the same results)
        "online": 2 * 3 * 2 + 2,
    }
    names = [job.name for job in jobs]
    assert len(names) == len(set(names))


def test_a_strategy_alias_is_its_own_optimization_of_the_same_strategy(tmp_path):
    jobs = {job.name: job for job in engine.plan_jobs(recipe_at(tmp_path), DOMAIN)}
    alias = jobs["optimize small/prune_more"]
    assert alias.params["strategy"] == "local_prune" and alias.params["options"]["conv"] == 0.5
    assert jobs["optimize small/local_prune"].params["options"]["finetune_epochs"] == 1
    assert alias.params["options"].keys() == jobs["optimize small/local_prune"].params["options"].keys()


def test_writing_out_a_default_option_plans_the_same_jobs(tmp_path):
    """Options are keyed with the config's defaults filled in: `conv: 0.3` where 0.3 is the default
    changes no job, and a variant that differs from a strategy only by written defaults is planned once."""
    from pilotlab.strategies import make_strategy_config
    default_conv = make_strategy_config("local_prune").conv
    before = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path), DOMAIN)}
    edited = RECIPE.replace("local_prune: {finetune_epochs: 1}",
                            f"local_prune: {{finetune_epochs: 1, conv: {default_conv}}}")
    assert edited != RECIPE
    after = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path, edited), DOMAIN)}
    assert after == before


def test_operator_types_in_another_order_are_the_same_dynamic_quantization(tmp_path):
    """Outside test: `op_types: [Gemm, MatMul]` (the default, [MatMul, Gemm], written in another order) ran the
    strategy's jobs again."""
    def optimize_keys(op_types: str) -> set[str]:
        text = RECIPE.replace("  prune_more:", f"  dq: {{use: dynamic_quant{op_types}}}\n  prune_more:").replace(
            "strategy: [baseline,", "strategy: [baseline, dq,")
        return {job.key for job in engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
                if job.kind == "optimize" and "dq" in job.name}
    assert optimize_keys("") == optimize_keys(", op_types: [Gemm, MatMul]") == \
        optimize_keys(", op_types: [Gemm, MatMul, Gemm]")
    assert optimize_keys("") != optimize_keys(", op_types: [MatMul]")


def test_renaming_a_dataset_names_its_jobs_anew_and_reruns_none(tmp_path):
    before = {job.key for job in engine.plan_jobs(recipe_at(tmp_path), DOMAIN)}
    renamed = RECIPE.replace("  train: {record", "  laps_data: {record").replace(
        "small: {epochs: 1}", "small: {epochs: 1, data: laps_data}").replace(
        "other: {epochs: 2}", "other: {epochs: 2, data: laps_data}")
    jobs = engine.plan_jobs(recipe_at(tmp_path, renamed), DOMAIN)
    assert "frames laps_data/simple_circuit cw" in {job.name for job in jobs}
    assert {job.key for job in jobs} == before


def test_the_same_recordings_listed_in_another_order_are_the_same_dataset(tmp_path):
    """Outside test: listing a dataset's recordings in another order retrained every network ("dependencies
    reordered"): a dataset is the set of its recordings (its frames in the order of their keys)."""
    two = RECIPE.replace("circuits: [simple_circuit], directions: [cw, ccw]", "circuits: [simple_circuit, "
                         "many_curves], directions: [cw, ccw]")
    before = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path, two), DOMAIN)}
    swapped = two.replace("[simple_circuit, many_curves], directions: [cw, ccw]",
                          "[many_curves, simple_circuit], directions: [ccw, cw]")
    assert {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path, swapped), DOMAIN)} == before


def test_changing_a_strategy_option_changes_only_its_jobs(tmp_path):
    before = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path), DOMAIN)}
    edited = recipe_at(tmp_path, RECIPE.replace("{use: local_prune, conv: 0.5}", "{use: local_prune, conv: 0.6}"))
    after = {job.name: job.key for job in engine.plan_jobs(edited, DOMAIN)}
    # prune_more's network is prepared anew (a prepare job is named by its options)
    renamed = {f"prepare {m}/l1_pruning (conv {conv:g})": conv for m in ("small", "other")
               for conv in (0.5, 0.6)}
    assert set(before) - set(after) == {name for name, conv in renamed.items() if conv == 0.5}
    assert set(after) - set(before) == {name for name, conv in renamed.items() if conv == 0.6}
    assert sorted(name for name in after if name in before and after[name] != before[name]) == sorted(
        [f"optimize {m}/prune_more" for m in ("small", "other")]
        + [f"{kind} {m}/prune_more on {h}" for kind in ("timing", "offline") for m in ("small", "other")
           for h in ("cpu", "cpu1")]
        + [f"online {m}/prune_more on {h} at simple_circuit cw" for m in ("small", "other") for h in ("cpu", "cpu1")])


def test_cuda_profiles_drive_no_reference_laps_and_are_planned(tmp_path):
    text = RECIPE.replace("hardware: [cpu, cpu1]", "hardware: [cpu, cuda]")
    jobs = engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    references = [job for job in jobs if job.kind == "online" and "artifact" not in job.deps]
    assert {job.labels["hardware"] for job in references} == {"cpu"}
    assert any(job.labels.get("hardware") == "cuda" for job in jobs if job.kind == "offline")


@pytest.mark.parametrize("edit, message", [
    (("finetune_epochs: 1}", "finetune_epoch: 1}"),
     ":9: strategies.local_prune: unknown option(s) finetune_epoch (did you mean 'finetune_epochs'?)"),
    (("{use: local_prune, conv: 0.5}", "{use: local_prun}"),
     ":10: strategies.prune_more.use: unknown strategy 'local_prun' (did you mean 'local_prune'?)"),
    (("{use: local_prune, conv: 0.5}", "{use: local_prune, conv: 1.5}"),
     ":10: strategies.prune_more: conv: 1.5 is not a fraction in [0, 1) (prune_more uses local_prune)"),
    # outside test: checked only when the optimize job ran, without file or key
    (("{use: local_prune, conv: 0.5}", "{use: cluster, clusters: 100000}"),
     ":10: strategies.prune_more: clusters: 100000 must be between 2 and 256 (int8 has 256 values) (prune_more uses cluster)"),
    (("{use: local_prune, conv: 0.5}", "{use: local_prune, conv: lots}"),
     ":10: strategies.prune_more: conv: 'lots' is not a number (prune_more uses local_prune)"),
    (("local_prune: {finetune_epochs: 1}", "local_prune: {use: global_prune}"),
     ":9: strategies.local_prune.use: 'local_prune' is a built-in strategy; give the variant of global_prune a new name"),
    (("strategy: [baseline,", "strategy: [baselin,"),
     ":13: matrix.strategy.0: unknown strategy 'baselin' (did you mean 'baseline'?)"),
    (("circuit: [simple_circuit]", "circuit: [simple_circiut]"),
     ":15: matrix.circuit.0: unknown circuit 'simple_circiut' (did you mean 'simple_circuit'?)"),
    (("hardware: [cpu, cpu1]", "hardware: [cpu, gpu]"),
     ":14: matrix.hardware.1: unknown hardware 'gpu'"),
    (("small: {epochs: 1}", "small: {epochs: 1, arch: pilotnett}"),
     ":6: models.small.arch: unknown arch 'pilotnett' (did you mean 'pilotnet'?); built-in archs: pilotnet, pilotnet_stacked (or bring your own"),
    (("small: {epochs: 1}", "small: {epochs: 1, options: {dropuot: 0.1}}"),
     ":6: models.small: model 'pilotnet': unknown option(s) dropuot (did you mean 'dropout'?)"),
    (("train: {record: {circuits: [simple_circuit],", "train: {bags: [missing.bag], record: {circuits: [simple_circuit],"),
     ":3: datasets.train.bags: missing.bag does not exist"),
    (("{use: local_prune, conv: 0.5}", "{use: [local_prune, baseline]}"),
     ":10: strategies.prune_more.use: `use` names one strategy (got a list); e.g. use: local_prune"),
    (("{use: local_prune, conv: 0.5}", "{use: {}}"),
     ":10: strategies.prune_more.use: `use` names one strategy (got a mapping); e.g. use: local_prune"),
    (("laps: 0.2}}", "laps: 0.2, camera: {width: 8}}}"),
     ":3: datasets.train.record.camera.width: Input should be greater than or equal to 16 (got 8)"),
    (("matrix:", "report: {compare_with: study2002}\nmatrix:"),
     ":11: report.compare_with: unknown study 'study2002' (did you mean 'study2022'?); known: study2022"),
    # outside test: strategy options that planned, then failed in the job (a ZeroDivisionError, a NaN stored
    # as null and refused under the strategy's built-in name, a format refused after 8 s of fine-tuning)
    (("conv: 0.5", "batch_size: 0"), "strategies.prune_more: batch_size: 0 must be at least 1 (prune_more uses local_prune)"),
    # outside test: lax validation took '3' for 3 and true for 1.0 ("1.0 is not a fraction")
    (("conv: 0.5", "conv: true"), "strategies.prune_more: conv: true is not a number (prune_more uses local_prune)"),
    (("conv: 0.5", "batch_size: '3'"), "strategies.prune_more: batch_size: '3' is not a number (write it without quotes)"),
    (("conv: 0.5", "lr: .nan"), "strategies.prune_more: lr: nan is not a finite number"),
    (("conv: 0.5", "lr: -1.0"), "strategies.prune_more: lr: -1.0 must be above 0"),
    (("conv: 0.5", "finetune_epochs: -1"), "strategies.prune_more: finetune_epochs: -1 must be at least 0"),
    (("conv: 0.5", "format: bogus"), "strategies.prune_more: format: Input should be 'checkpoint', 'torchscript' or 'onnx'"),
    (("conv: 0.5", "version: 99"), ":10: strategies.prune_more.version: version is not an option"),
    # outside test: a value fitting no arm of a union was said at pydantic's tag (references.1.literal['explicit',
    # 'expert']) in one arm's words; `tolerance: maybe` did not say that true is allowed
    (("matrix:", "online: {references: [explicit, expertt]}\nmatrix:"),
     ":11: online.references.1: should be 'explicit' or 'expert' or a valid dictionary (got 'expertt') "
     "(did you mean 'expert'?)"),
    (("small: {epochs: 1}", "small: {epochs: 1, labels: autoo}"),
     ":6: models.small.labels: 'labels' should be 'auto' or a valid dictionary (got 'autoo') (did you mean 'auto'?)"),
    (("matrix:", "online: {tolerance: maybe}\nmatrix:"),
     ":11: online.tolerance: tolerance is true (the default search), false, or a mapping of the search's settings"),
    # outside test: `directions: [cw, cw]` recorded the circuit twice and trained on every frame twice, silently
    (("directions: [cw, ccw]", "directions: [cw, cw]"),
     ":3: datasets.train.record.directions: 'cw' is listed twice; list each once"),
    (("circuits: [simple_circuit], laps: 0.1", "circuits: [simple_circuit, simple_circuit], laps: 0.1"),
     ":4: datasets.test.record.circuits: 'simple_circuit' is listed twice; list each once"),
    (("matrix:", "online: {directions: [ccw, ccw]}\nmatrix:"), ":11: online.directions: 'ccw' is listed twice"),
    (("matrix:", "online: {timing: lockstep, tolerance: true}\nmatrix:"),
     ":11: online: a latency tolerance search means nothing in the lockstep timing mode"),
    (("matrix:", "online: {tolerance: {only: [{circut: simple_circuit}]}}\nmatrix:"),
     ":11: online.tolerance.only.0: 'circut' is not an axis of a lap cell (did you mean 'circuit'?)"),
    # outside test: a malformed entry was said at the `only:` line, whichever entry it was
    (("matrix:", "online:\n  tolerance:\n    only:\n      - {circuit: simple_circuit}\n      - simple_circuit\nmatrix:"),
     ":15: online.tolerance.only.1: each entry of only is a partial cell, e.g. {circuit: montreal, strategy: "
     "baseline}; got 'simple_circuit'"),
    (("matrix:", "online: {tolerance: {only: [{circuit: simple_circuit}, {strategy: prune_mor}]}}\nmatrix:"),
     ":11: online.tolerance.only.1.strategy: strategy 'prune_mor' names no lap of the matrix (did you mean "
     "'prune_more'?); its laps' strategy names: baseline, expert, explicit, local_prune, prune_more"),
    # outside test: a misspelt name beside a right one in a list was taken in silence
    (("matrix:", "online:\n  tolerance:\n    only:\n      - {circuit: [simple_circuit, montrael]}\nmatrix:"),
     ":14: online.tolerance.only.0.circuit: circuit 'montrael' names no lap of the matrix"),
    (("matrix:", "online: {tolerance: {only: [{model: explicit}]}}\nmatrix:"),
     "its laps' model names: other, reference, small; the reference brains are model `reference`"),
    (("matrix:", "online: {tolerance: {only: [{model: small, strategy: prune_more, hardware: cpu1}, {model: reference, "
                 "hardware: cpu1}]}}\nmatrix:"),
     ":11: online.tolerance.only.1: {model: reference, hardware: cpu1} names no lap cell of the matrix (no lap has all "
     "of it); name cells the matrix drives (the reference brains are model `reference`, driven on the first CPU"),
])
def test_recipe_errors_name_the_line_and_key(tmp_path, edit, message):
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, RECIPE.replace(*edit)), DOMAIN)
    assert message in str(caught.value)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("old, new, message", [
    ("  local_prune: {finetune_epochs: 1}\n", "  local_prune: {finetune_epochs: 1}\n  global_prune: {amount: 0.3, epoch: 1}\n",
     ":10: strategies.global_prune: unknown option(s) epoch"),
    ("  local_prune: {finetune_epochs: 1}\n", "  local_prune: {finetune_epochs: 1}\n  spare: {use: local_prun}\n",
     ":10: strategies.spare.use: unknown strategy 'local_prun' (did you mean 'local_prune'?)"),
    ("  other: {epochs: 2}\n", "  other: {epochs: 2}\n  spare: {options: {dropuot: 0.1}}\n",
     ":8: models.spare: model 'pilotnet': unknown option(s) dropuot (did you mean 'dropout'?)"),
    ("  other: {epochs: 2}\n", "  other: {epochs: 2}\n  spare: {data: trian}\n",
     ":8: models.spare.data: dataset 'trian' is not defined (did you mean 'train'?); datasets: train, test"),
    ("  other: {epochs: 2}\n", "  other: {epochs: 2}\n  spare: {network: nope.py:Net}\n",
     ":8: models.spare.network: nope.py: no such file"),
    ("  test: {record", "  spare: {bags: [missing.bag]}\n  test: {record", ":4: datasets.spare.bags: missing.bag does not exist"),
    ("  test: {record", "  spare: {record: {circuits: [simple_circiut]}}\n  test: {record",
     ":4: datasets.spare.record.circuits: unknown circuit 'simple_circiut'"),
    ("matrix:", "circuits:\n  spare: {csv: missing.csv}\nmatrix:", ":12: circuits.spare.csv: missing.csv does not exist"),
    ("matrix:", "hardware:\n  spare: {latency_file: missing.json}\nmatrix:",
     ":12: hardware.spare.latency_file: missing.json does not exist"),
    # outside test: a typo of a built-in name, without `use`, was said of a `use` key the recipe did not have
    ("  local_prune: {finetune_epochs: 1}\n", "  local_prune: {finetune_epochs: 1}\n  global_prun: {amount: 0.3}\n",
     ":10: strategies.global_prun: 'global_prun' is not a built-in strategy (did you mean 'global_prune'?)"),
    # outside test: label ranges were checked only by the training ("each range needs lo < hi", no key)
    ("  other: {epochs: 2}\n", "  other: {epochs: 2}\n  spare: {labels: {v: [13, 5], w: [-1.6, 1.6]}}\n",
     ":8: models.spare.labels: v: [13.0, 5.0] is not a range [lo, hi] of finite numbers with lo < hi"),
    ("  other: {epochs: 2}\n", "  other: {epochs: 2}\n  spare: {labels: {v: [5, 13]}}\n",
     ":8: models.spare.labels: give the ranges of v and w"),
    # outside test: these were taken and did nothing (every job the same); a circuit is a loop, 6 m wide
    ("matrix:", "circuits:\n  spare: {csv: x.csv, road_width: -3}\nmatrix:", ":12: circuits.spare.road_width: unknown key 'road_width'; expected one of: csv"),
    ("matrix:", "circuits:\n  spare: {csv: x.csv, closed: false}\nmatrix:", ":12: circuits.spare.closed: unknown key 'closed'"),
])
def test_definitions_the_matrix_does_not_use_are_validated_too(tmp_path, old, new, message):
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, RECIPE.replace(old, new, 1)), DOMAIN)
    assert message in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize("path, message", [
    ("a" * 5000, "datasets.train.bags: aaaaa"),
    ("/proc/self/mem", ":3: datasets.train.bags: /proc/self/mem is a system file (below /proc), not data"),
    ("/dev/zero", ":3: datasets.train.bags: /dev/zero is a system file (below /dev), not data"),
    ("/", "datasets.train.bags: / is a folder holding neither metadata.yaml (a ROS2 bag) nor data.csv"),
    ("~no_such_user_here/run.bag", "cannot be a path: Could not determine home directory"),
])
def test_an_input_that_is_not_data_is_one_line_at_once(tmp_path, path, message):
    text = RECIPE.replace("train: {record: {circuits: [simple_circuit],", f"train: {{bags: ['{path}'], record: {{circuits: [simple_circuit],")
    started = time.monotonic()
    with pytest.raises(MatrixError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    assert message in str(caught.value)
    assert "\n" not in str(caught.value) and len(str(caught.value)) < 400
    assert time.monotonic() - started < 5


@pytest.mark.parametrize("old, new, message", [
    ("matrix:", "circuits:\n  x: {csv: BIG}\nmatrix:", "circuits.x.csv: BIG is a folder; give a file"),
    ("  test: {record", "  spare: {folders: [BIG]}\n  test: {record",
     "datasets.spare.folders: BIG is a folder holding neither metadata.yaml (a ROS2 bag) nor data.csv"),
    ("  test: {record", "  spare: {bags: [recipe.yaml]}\n  test: {record",
     "datasets.spare.bags: recipe.yaml is not a bag: a ROS1 bag ends in .bag"),
    ("  other: {epochs: 2}\n", "  other: {epochs: 2}\n  spare: {arch: pilotnet, weights: BIG}\n",
     "models.spare.weights: BIG is a folder; give a file"),
    ("matrix:", "hardware:\n  spare: {latency_file: BIG}\nmatrix:", "hardware.spare.latency_file: BIG is a folder"),
])
def test_a_folder_where_a_file_is_expected_fails_before_anything_is_hashed(tmp_path, monkeypatch, old, new, message):
    import matrix.inputhash
    big = tmp_path / "home"                  # a folder of anything (a home folder of 6 GB)
    (big / "sub").mkdir(parents=True)
    (big / "sub" / "data.bin").write_bytes(b"0" * 1000)
    monkeypatch.setattr(matrix.inputhash, "_folder_files", lambda folder: pytest.fail(f"{folder} was walked"))
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, RECIPE.replace(old, new.replace("BIG", str(big)), 1)), DOMAIN)
    assert message.replace("BIG", str(big)) in str(caught.value) and "\n" not in str(caught.value)


def test_shipped_recipes_plan(tmp_path, monkeypatch):
    """Every shipped recipe plans; one over BehaviorMetrics' worlds needs them beside the repository
    (../shared/data/bm_worlds): without them its plan is the one-line error that says where it looked."""
    monkeypatch.delenv("PILOTLAB_BM_ASSETS", raising=False)
    for recipe in sorted(Path(__file__).resolve().parents[2].glob("recipes/*.yaml")):
        loaded = load_recipe(recipe, DOMAIN)
        assets = loaded.config.worlds.assets
        if assets is not None and not (recipe.parent / assets).is_dir():
            with pytest.raises(RecipeError, match="worlds.assets: .* does not exist"):
                engine.plan_jobs(loaded, DOMAIN)
            continue
        jobs = engine.plan_jobs(loaded, DOMAIN)
        assert jobs and {"train", "optimize", "timing", "offline", "online"} <= set(kinds(jobs))
        assert all(0 < KINDS.get(job.kind).typical(job.params) < 3600 for job in jobs)   # a guess for each


def test_a_cold_store_guesses_a_lap_with_a_tolerance_search_as_several_laps(tmp_path):
    """The scheduler's first guesses (matrix.times): a lap cell with its latency-tolerance search drives a
    lap per fixed latency above 0 and log2(widest bracket / step) to bisect, each a share of a plain lap (the
    completed ones longer, the lost ones cut short); a training's time follows its epochs."""
    laps = [job for job in engine.plan_jobs(load_recipe(ROOT / "recipes/study2022.yaml", DOMAIN), DOMAIN)
            if job.kind == "online"]
    searched = [job.params for job in laps if job.params["tolerance"] is not None]
    assert searched
    online, plain = KINDS.get("online"), dict(searched[0], tolerance=None)
    from pilotlab.specs.guesses import SEARCH_SHARE, SETUP_S as setup   # setup: the simulator's, whatever the laps
    ratio = (online.typical(searched[0]) - setup) / (online.typical(plain) - setup)
    from pilotlab.specs.online import ToleranceSpec
    tolerance = ToleranceSpec.model_validate(searched[0]["tolerance"])   # the fixed laps above 0 and log2(100/10)
    assert tolerance.bisection_laps == pytest.approx(math.log2(10))       # to bisect, lost laps cut short
    assert 0 < SEARCH_SHARE < 1 and ratio == pytest.approx(1 + SEARCH_SHARE * (2 + math.log2(10)))
    assert abs(online.typical(dict(plain, laps=3)) - setup - 3 * (online.typical(plain) - setup)) < 1e-9
    # a lap of Montreal is about three of simple_circuit (by BehaviorMetrics' timeouts); a user's circuit, one
    simple, montreal = (online.typical(dict(plain, circuit=name)) - setup for name in ("simple_circuit", "montreal"))
    assert 3.0 < montreal / simple < 3.5 and online.typical(dict(plain, circuit="tracks/mine.csv")) - setup == simple
    record = KINDS.get("record")
    assert 3.0 < record.typical({"circuit": "montreal"}) / record.typical({"circuit": "simple_circuit"}) < 3.5
    # a job for the cuda profile, planned on a host without a GPU, is "not applicable" at once (the study's
    # 84 were priced as work: "about 4:21:22 left" for a 20-minute run); with a GPU it is work
    cuda = [job for job in laps if job.params["hardware"]["device"] == "cuda"]
    no_gpu, gpu = dict(cuda[0].params, host={"gpu": None}), dict(cuda[0].params, host={"gpu": "NVIDIA H200"})
    assert online.typical(no_gpu) == 0.1 and online.typical(gpu) > 1
    for kind in ("timing", "offline", "optimize"):
        params = {"hardware": {"name": "cuda", "device": "cuda"}, "options": {}}
        assert KINDS.get(kind).typical(dict(params, host={"gpu": None})) == 0.1
        assert KINDS.get(kind).typical(dict(params, host={"gpu": "NVIDIA H200"})) >= 1.0
        assert KINDS.get(kind).typical(dict(params, host=None)) >= 1.0   # on whichever worker has the GPU
    train = KINDS.get("train")
    assert train.typical({"epochs": 40}) == 2 * train.typical({"epochs": 20}) == 2 * train.typical({})
    # a fine-tune is guessed by its epochs (the longest starts first); a shared preparation's are its prepare job's
    planned = engine.plan_jobs(load_recipe(ROOT / "recipes/quickstart.yaml", DOMAIN), DOMAIN)
    optimize = {job.params["strategy"]: job.params for job in planned if job.kind == "optimize"}
    prepare = next(job.params for job in planned if job.kind == "prepare")
    guess = {strategy: KINDS.get("optimize").typical(params) for strategy, params in optimize.items()}
    assert KINDS.get("prepare").typical(prepare) > max(guess.values()) and guess["baseline"] == guess["dynamic_quant"]
    assert guess["structured_prune_int8"] == guess["onnxruntime_int8"]     # both calibrate and convert
    longer = dict(prepare, options=dict(prepare["options"], finetune_epochs=8))
    assert KINDS.get("prepare").typical(longer) > KINDS.get("prepare").typical(prepare)
    # a QAT epoch (fp32, fake quantization) is about three of another fine-tune's (the study's CQAT ran 31 s
    # where its guess said 15); a channel-pruned network's epochs cost its share of channels kept
    study = engine.plan_jobs(load_recipe(ROOT / "recipes/study2022.yaml", DOMAIN), DOMAIN)
    cpu = {job.name.removeprefix("optimize pilotnet/"): job for job in study if job.kind == "optimize"}
    fit = {name: KINDS.get("optimize").typical(cpu[name].params) for name in ("qat", "qat_litert_int8", "global_prune")}
    assert fit["qat"] == fit["qat_litert_int8"] > fit["global_prune"]     # one QAT epoch > two pruning ones
    channels = {job.params["options"]["amount"]: KINDS.get("prepare").typical(job.params) for job in study
                if job.kind == "prepare" and job.params["preparation"] == "channel_pruning"}
    from pilotlab.specs.guesses import BASE_S, EPOCH_S
    assert channels == {0.3: pytest.approx(BASE_S + 2 * 0.7 * EPOCH_S), 0.65: pytest.approx(BASE_S + 12 * 0.35 * EPOCH_S)}


def test_a_timing_that_will_not_time_does_not_hold_the_host():
    """The study's 24 CUDA timings on a host without a GPU each ran alone, holding both cores for the
    tenth of a second they take to say "not applicable"; on a host with a GPU (or any worker's), they time."""
    timing = KINDS.get("timing")
    params = {"hardware": {"name": "cuda", "device": "cuda"}}
    assert not timing.runs_alone(dict(params, host={"gpu": None}))
    assert timing.runs_alone(dict(params, host={"gpu": "NVIDIA H200"})) and timing.runs_alone(dict(params, host=None))
    assert timing.runs_alone({"hardware": {"name": "cpu", "device": "cpu"}, "host": {"gpu": None}})


def test_the_plan_notes_searched_laps_and_cuda_jobs_that_end_at_once():
    """Outside tests: the plan did not say which laps drive a tolerance search (a dozen laps' worth each),
    and showed the CUDA cells as new work on a host without a GPU."""
    jobs = engine.plan_jobs(load_recipe(ROOT / "recipes/study2022.yaml", DOMAIN), DOMAIN)
    notes = {job.name: KINDS.get(job.kind).note(job.params) for job in jobs}
    assert notes["online pilotnet/baseline on cpu at montreal cw"] == "latency tolerance search"
    assert notes["online pilotnet/qat on cpu at montreal cw"] == ""        # the study searches Montreal's baseline only
    assert notes["record train/many_curves cw"] == ""
    cuda = next(job for job in jobs if job.kind == "timing" and job.params["hardware"]["device"] == "cuda")
    assert KINDS.get("timing").note(dict(cuda.params, host={"gpu": None})) == "not applicable here: no GPU on this host"
    assert KINDS.get("timing").note(dict(cuda.params, host={"gpu": "NVIDIA H200"})) == ""


def network_laps(jobs):
    return [job for job in jobs if job.kind == "online" and job.params.get("brain") == "network"]


def cells(jobs, kind: str) -> dict:
    return {(j.labels["model"], j.labels["strategy"], j.labels["hardware"]): j for j in jobs if j.kind == kind}


def test_network_laps_replay_their_timing_jobs_latencies(tmp_path):
    jobs = engine.plan_jobs(recipe_at(tmp_path), DOMAIN)
    timing, offline = cells(jobs, "timing"), cells(jobs, "offline")
    for lap in network_laps(jobs):
        assert lap.params["timing"] == "replay" and lap.params["tolerance"] is None
        cell = (lap.labels["model"], lap.labels["strategy"], lap.labels["hardware"])
        assert lap.deps["timing"] is timing[cell] and "scale_reference" not in lap.deps
        assert offline[cell].deps["timing"] is timing[cell]
        assert not any(dep.kind == "offline" for dep in lap.dep_jobs())


def test_a_timing_job_is_fed_the_training_frames_not_the_test_set(tmp_path):
    jobs = engine.plan_jobs(recipe_at(tmp_path), DOMAIN)
    for job in cells(jobs, "timing").values():
        optimize = job.deps["artifact"]
        assert optimize.kind == "optimize" and job.deps["frames"] == optimize.deps["calibration"]
        assert {dep.name for dep in job.deps["frames"]} == {"frames train/simple_circuit cw",
                                                          "frames train/simple_circuit ccw"}
        assert job.params["batch"] == 64 and job.params["hardware"]["name"] == job.labels["hardware"]


def test_a_timing_job_runs_alone_and_an_offline_job_beside_others(tmp_path):
    from matrix.kinds import KINDS
    jobs = engine.plan_jobs(recipe_at(tmp_path), DOMAIN)
    alone = {job.kind for job in jobs if KINDS.get(job.kind).runs_alone(job.params)}
    assert "timing" in alone and "offline" not in alone and "online" not in alone   # replayed laps: beside others


@pytest.mark.parametrize("edit", [("laps: 0.1, seed: 3", "laps: 0.1, seed: 4"),
                                  ("laps: 0.1, seed: 3", "laps: 0.2, seed: 3")])
def test_editing_the_test_set_reruns_only_the_offline_jobs(tmp_path, edit):
    """The laps replay the timing jobs' latencies, which never read the test set: an edit of the test set
    re-times nothing and reruns no lap (the most expensive jobs), only its recording and the MSEs."""
    before = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path), DOMAIN)}
    after = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path, RECIPE.replace(*edit)), DOMAIN)}
    assert set(after) == set(before)
    changed = {name for name in after if after[name] != before[name]}
    assert {name.split()[0] for name in changed} == {"record", "frames", "offline"}
    assert {name for name in changed if name.startswith("offline")} == {
        name for name in after if name.startswith("offline")}
    assert "record test/simple_circuit cw" in changed and not any("train/" in name for name in changed)


def test_the_throughput_batch_re_times_and_reruns_the_laps(tmp_path):
    before = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path), DOMAIN)}
    edited = RECIPE.replace("matrix:", "offline: {batch: 32}\nmatrix:")
    after = {job.name: job.key for job in engine.plan_jobs(recipe_at(tmp_path, edited), DOMAIN)}
    changed = {name.split()[0] for name in after if after[name] != before[name]}
    assert changed == {"timing", "offline", "online"}


def test_scaled_latencies_and_the_tolerance_search(tmp_path):
    text = RECIPE + "online: {latency_scale_to_ms: 124, tolerance: true}\n"
    jobs = engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    timing = cells(jobs, "timing")
    for lap in network_laps(jobs):
        assert lap.params["latency_scale_to_ms"] == 124
        assert lap.params["tolerance"] == {"fixed_ms": [0.0, 100.0, 200.0], "max_ms": 1000.0, "step_ms": 10.0,
                                               "probe": 0.7}
        base = (lap.labels["model"], "baseline", lap.labels["hardware"])
        assert lap.deps["scale_reference"] is timing[base]
    references = [job for job in jobs if job.kind == "online" and job.params["brain"] != "network"]
    assert references and all(job.params["tolerance"] is not None and not job.deps for job in references)


def test_a_tolerance_search_on_a_longer_circuit_starts_from_the_shortest_circuits_lap(tmp_path):
    """Each brain's Montreal lap has its simple_circuit lap (same hardware and direction) as its
    `tolerance_hint`; the shortest circuit's lap has none, and without a tolerance search nothing does."""
    text = RECIPE.replace("circuit: [simple_circuit]", "circuit: [montreal, simple_circuit]")
    plain = engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    assert not any("tolerance_hint" in job.deps for job in plain if job.kind == "online")
    jobs = engine.plan_jobs(recipe_at(tmp_path, text + "online: {tolerance: true, directions: [cw, ccw]}\n"), DOMAIN)
    laps = {job.name: job for job in jobs if job.kind == "online"}
    hinted = {name: job for name, job in laps.items() if "tolerance_hint" in job.deps}
    assert len(hinted) == len(laps) // 2 and all(" at montreal " in name for name in hinted)
    for name, job in hinted.items():
        scout = job.deps["tolerance_hint"]
        assert scout is laps[name.replace(" at montreal ", " at simple_circuit ")]
        assert "tolerance_hint" not in scout.deps and scout.params["direction"] == job.params["direction"]
    assert {"online explicit on cpu at montreal cw", "online expert on cpu at montreal ccw"} <= set(hinted)
    assert not any(name.startswith(("online explicit on cpu1", "online expert on cpu1")) for name in laps)
    live = engine.plan_jobs(recipe_at(tmp_path, text + "online: {timing: measured}\n"), DOMAIN)
    assert {"online expert on cpu at montreal cw", "online expert on cpu1 at montreal cw"} <= {j.name for j in live}


def test_a_tolerance_search_can_be_kept_to_the_cells_a_recipe_names(tmp_path):
    """`tolerance: {only: [...]}` searches the lap cells an entry names (the rest drive their laps alone); a
    searched lap has the same key as with `tolerance: true`, and takes its hint from the brain's shortest
    searched circuit only."""
    text = RECIPE.replace("circuit: [simple_circuit]", "circuit: [montreal, simple_circuit]")
    every = {j.name: j for j in engine.plan_jobs(recipe_at(tmp_path, text + "online: {tolerance: true}\n"), DOMAIN)
             if j.kind == "online"}
    only = ("online:\n  tolerance:\n    only: [{circuit: simple_circuit, hardware: cpu},\n"
            "           {circuit: montreal, strategy: baseline, model: [small, other]}, {model: reference, strategy: expert}]\n")
    laps = {j.name: j for j in engine.plan_jobs(recipe_at(tmp_path, text + only), DOMAIN) if j.kind == "online"}
    searched = {name for name, job in laps.items() if job.params["tolerance"] is not None}
    assert searched == {name for name in laps if " at simple_circuit " in name and " on cpu " in name} | {
        "online small/baseline on cpu at montreal cw", "online small/baseline on cpu1 at montreal cw",
        "online other/baseline on cpu at montreal cw", "online other/baseline on cpu1 at montreal cw",
        "online expert on cpu at montreal cw"}
    assert all(laps[name].key == every[name].key for name in searched if " on cpu1 " not in name)
    unsearched = "online small/local_prune on cpu at montreal cw"
    assert laps[unsearched].params == {**every[unsearched].params, "tolerance": None}
    hinted = {name for name, job in laps.items() if "tolerance_hint" in job.deps}
    # cpu1's simple_circuit laps are not searched: its baseline's Montreal search has no searched neighbour
    assert hinted == {"online small/baseline on cpu at montreal cw", "online other/baseline on cpu at montreal cw",
                      "online expert on cpu at montreal cw"}


def test_a_tolerance_entry_may_name_a_strategy_planned_as_another(tmp_path):
    """Outside test: `dq2: {use: dynamic_quant}` is planned as dynamic_quant (one definition), and
    `only: [{strategy: dq2}]` named no lap cell; it names the laps it is planned as."""
    text = RECIPE.replace("strategy: [baseline, local_prune, prune_more]", "strategy: [baseline, local_prune, again]").replace(
        "  prune_more: {use: local_prune, conv: 0.5}\n", "  again: {finetune_epochs: 1, use: local_prune}\n")
    laps = [j for j in engine.plan_jobs(recipe_at(tmp_path, text + "online: {tolerance: {only: [{strategy: again}]}}\n"),
                                        DOMAIN) if j.kind == "online" and j.params["tolerance"] is not None]
    assert laps and {job.labels["strategy"] for job in laps} == {"local_prune"}


def test_a_combination_without_a_model_is_refused_with_its_message_when_laps_take_hints(tmp_path):
    """Found by the slow fuzz: the scouts were looked up over every combination, and one without a
    model raised KeyError before the planner reached it to refuse it."""
    text = RECIPE.replace("circuit: [simple_circuit]", "circuit: [montreal, simple_circuit]\n  include:\n"
                          "    - {strategy: fp16, circuit: montreal}") + "online: {tolerance: true}\n"
    with pytest.raises(MatrixError, match="has no model"):
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)


def test_a_hardware_latency_file_is_replayed_instead_of_this_hosts_timings(tmp_path):
    (tmp_path / "timings").mkdir()
    (tmp_path / "timings" / "jetson.csv").write_text("model,strategy,latency_ms\n,,25\n")
    text = RECIPE.replace("hardware: [cpu, cpu1]", "hardware: [jetson]").replace(
        "matrix:", "hardware:\n  jetson: {threads: 1, latency_file: timings/jetson.csv}\nmatrix:")
    jobs = engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    for lap in network_laps(jobs):
        assert "timing" not in lap.deps and "latency_file" in lap.inputs
        assert lap.params["latency_for"] == {"model": lap.labels["model"], "strategy": lap.labels["strategy"]}
    missing = text.replace("timings/jetson.csv", "timings/nano.csv")
    with pytest.raises(RecipeError, match="nano.csv does not exist"):
        engine.plan_jobs(recipe_at(tmp_path, missing), DOMAIN)


@pytest.mark.parametrize("content, message", [
    (b"\xff\xfe\x00garbage", "cannot be read ("),
    (b"strategy,ms\nbaseline,5\n", "a header and a latency_ms column"),
    (b"", "a header and a latency_ms column"),
    (b"latency_ms\n1e9\n", "finite milliseconds from 0 to 60000, at least one; got 1 sample(s), the largest 1e+09"),
    (b"latency_ms\nfast\n", "latency_ms must be a number of milliseconds in every row"),
    (b"model,strategy,latency_ms\nnot_this_one,,25\n", "no latency_ms rows for model"),
])
def test_a_latency_file_is_checked_when_the_recipe_is_planned(tmp_path, content, message):
    """Outside test: a latency file that is not UTF-8, empty, without rows for the matrix's models or
    with a sample of 1e9 ms planned; the run then spent the offline jobs' time before the lap failed
    with a traceback (UnicodeDecodeError) or ran for hours. Now plan says it, with the file's line."""
    (tmp_path / "timings").mkdir()
    (tmp_path / "timings" / "jetson.csv").write_bytes(content)
    text = RECIPE.replace("hardware: [cpu, cpu1]", "hardware: [jetson]").replace(
        "matrix:", "hardware:\n  jetson: {threads: 1, latency_file: timings/jetson.csv}\nmatrix:")
    for recipe in (text, RECIPE.replace("matrix:", "hardware:\n  spare: {latency_file: timings/jetson.csv}\nmatrix:")):
        if "no latency_ms rows" in message and "spare" in recipe:
            continue                       # a profile the matrix does not use: no lap's rows to look for
        with pytest.raises(RecipeError) as caught:
            engine.plan_jobs(recipe_at(tmp_path, recipe), DOMAIN)
        assert message in str(caught.value) and "latency_file" in str(caught.value) and "\n" not in str(caught.value)


def test_use_naming_a_variant_of_the_recipe_says_to_name_a_built_in_strategy(tmp_path):
    text = RECIPE.replace("prune_more: {use: local_prune, conv: 0.5}", "prune_more: {use: chained}\n  chained: {use: local_prune}")
    with pytest.raises(RecipeError, match="`use` names a built-in strategy, and 'chained' is a variant of this recipe"):
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)


def test_user_circuits_and_csv_paths_are_found_beside_the_recipe_wherever_it_is_planned_from(tmp_path, monkeypatch):
    project, elsewhere = tmp_path / "project", tmp_path / "elsewhere"
    (project / "circuits").mkdir(parents=True)
    elsewhere.mkdir()
    for path in (project / "circuits" / "oval.csv", project / "ring.csv"):
        path.write_text("\n".join(f"{x},{y}" for x, y in stadium()))
    (project / "recipe.yaml").write_text(RECIPE.replace("train: {record: {circuits: [simple_circuit]",
                                                        "train: {record: {circuits: [oval, ring.csv]")
                                         .replace("circuit: [simple_circuit]", "circuit: [oval, ring.csv]"))
    monkeypatch.chdir(elsewhere)
    jobs = engine.plan_jobs(load_recipe(Path("../project/recipe.yaml"), DOMAIN), DOMAIN)
    records = [job for job in jobs if job.kind == "record"]
    assert {job.params["circuit"] for job in records} == {"simple_circuit", "oval", "ring"}
    # the jobs read the files their inputs name (whatever the worker's folder); keys follow content, not place
    assert {job.inputs["circuit_csv"].path for job in records if "circuit_csv" in job.inputs} == \
        {str(project / "circuits" / "oval.csv"), str(project / "ring.csv")}
    for name, csv in (("oval", project / "circuits" / "oval.csv"), ("ring.csv", project / "ring.csv")):  # any axis
        lap = next(job for job in jobs if job.kind == "online" and job.labels["circuit"] == name)
        assert lap.inputs["circuit_csv"].path == str(csv)
    moved = tmp_path / "moved"
    project.rename(moved)
    assert {job.key for job in engine.plan_jobs(load_recipe(Path("../moved/recipe.yaml"), DOMAIN), DOMAIN)} == \
        {job.key for job in jobs}


def test_a_user_circuit_named_like_a_built_in_one_is_refused_not_passed_over(tmp_path, monkeypatch):
    (tmp_path / "circuits").mkdir()
    (tmp_path / "circuits" / "simple_circuit.csv").write_text("\n".join(f"{x},{y}" for x, y in stadium()))
    with pytest.raises(RecipeError, match="simple_circuit.csv has the name of a built-in circuit, which it does not "
                                          r"replace; rename the file \(e.g. my_simple_circuit.csv\)"):
        engine.plan_jobs(recipe_at(tmp_path), DOMAIN)


def test_the_built_in_circuit_s_own_file_in_a_user_folder_is_no_second_circuit(tmp_path, monkeypatch):
    """Outside test: PILOTLAB_CIRCUITS pointed at BehaviorMetrics' centrelines (pilotlab's built-ins, byte for
    byte) and every built-in circuit was refused."""
    from importlib import resources
    (tmp_path / "circuits").mkdir()
    shipped = resources.files("pilotlab.circuits") / "data" / "simple_circuit.csv"
    (tmp_path / "circuits" / "simple_circuit.csv").write_bytes(shipped.read_bytes().replace(b"\n", b"\r\n"))
    jobs = engine.plan_jobs(recipe_at(tmp_path), DOMAIN)
    assert not any("circuit_csv" in job.inputs for job in jobs)    # the built-in, as without the file


def test_a_recipe_circuit_named_like_a_built_in_one_is_refused_not_driven_in_its_place(tmp_path):
    (tmp_path / "oval.csv").write_text("\n".join(f"{x},{y}" for x, y in stadium()))
    text = RECIPE + "circuits: {simple_circuit: {csv: oval.csv}}\n"
    with pytest.raises(RecipeError, match=r"circuits.simple_circuit: 'simple_circuit' is the name of a built-in "
                                          r"circuit, .* \(e.g. my_simple_circuit\)"):
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    renamed = engine.plan_jobs(recipe_at(tmp_path, RECIPE + "circuits: {my_oval: {csv: oval.csv}}\n"), DOMAIN)
    assert any(job.kind == "online" for job in renamed)


def test_a_dls_folder_is_keyed_by_data_csv_and_the_images_it_names_only(tmp_path):
    from tests.pilotlab.data.bagfiles import images
    from tests.pilotlab.data.test_folder import make_folder
    folder = make_folder(tmp_path / "dls", images(3))
    text = RECIPE.replace("test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 3}}", "test: {folders: [dls]}")

    def frames_key() -> str:
        return next(job.key for job in engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN) if job.name == "frames test/dls")

    before = frames_key()
    (folder / "notes.txt").write_text("an operator's notes")
    (folder / "unused.png").write_bytes((folder / "0.png").read_bytes())
    assert frames_key() == before                       # nothing a reader reads changed
    (folder / "2.png").write_bytes((folder / "0.png").read_bytes())
    assert frames_key() != before                       # an image a row names did
    (folder / "data.csv").write_text((folder / "data.csv").read_text() + "missing.png,1,0,1650000001\n")
    with pytest.raises(RecipeError, match=r"datasets.test.folders: .*data.csv: row 4 names image 'missing.png', "
                                          r"which is not in"):
        frames_key()


def test_a_circuit_csv_that_is_no_lap_is_the_recipe_s_error_at_plan(tmp_path):
    (tmp_path / "circuits").mkdir()
    (tmp_path / "circuits" / "open.csv").write_text("0,0\n50,0\n100,0\n100,50\n100,100\n50,100\n")
    with pytest.raises(RecipeError, match=r":15: matrix.circuit: circuit 'open' .* the centreline is not a lap"):
        engine.plan_jobs(recipe_at(tmp_path, RECIPE.replace("circuit: [simple_circuit]", "circuit: [open]")), DOMAIN)


def test_gc_keeps_the_jobs_planned_for_another_host():
    """Outside test: `taskset -c 0 pilotlab gc` (one core: another host fingerprint) would have removed
    every timing and lap of the recipe; those are another host's to collect."""
    from pilotlab.domain import planned_on_another_host
    from pilotlab.hardware import host_fingerprint
    here = host_fingerprint()
    assert planned_on_another_host({"params": {"host": here}}) is None
    assert planned_on_another_host({"params": {"circuit": "simple_circuit"}}) is None
    other = planned_on_another_host({"params": {"host": {**here, "cores": here["cores"] + 1}}})
    assert other.startswith("planned for another host (") and f"{here['cores'] + 1} cores" in other


BAG_DATASET = "train: {bags: [run.bag]%s, record: {circuits: [simple_circuit],"


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
@pytest.mark.parametrize("topics, message", [
    # outside test: plan passed, the run failed minutes later on the command topic, then on the image one
    (", topics: {image: /cam/image_raw, command: /cmd_vel}",
     ":3: datasets.train.topics: bag run.bag: no image topic '/cam/image_raw' and no command topic '/cmd_vel'; "
     "topics present: /F1ROS/cameraL/image_raw (sensor_msgs/msg/Image), /F1ROS/cmd_vel (geometry_msgs/msg/Twist)"),
    (", topics: {command: /cmd_vel}", ":3: datasets.train.topics.command: bag run.bag: no command topic '/cmd_vel'"),
    (", topics: {image: /F1ROS/cameraL/image_raw, command: /cmd_vel}",
     ":3: datasets.train.topics.command: bag run.bag: no command topic '/cmd_vel';"),
])
def test_a_dataset_topic_its_bag_lacks_fails_the_plan_at_the_key_to_change(tmp_path, kind, topics, message):
    from tests.pilotlab.data.bagfiles import drive_bag, images
    bag = tmp_path / ("run.bag" if kind == "ros1" else "run")
    drive_bag(bag, kind, images(3))
    text = RECIPE.replace("train: {record: {circuits: [simple_circuit],", BAG_DATASET.replace("run.bag", bag.name) % topics)
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    assert message.replace("run.bag", bag.name) in str(caught.value)
    assert "name the bag's topics in the dataset" in str(caught.value) and "\n" not in str(caught.value)


def test_a_bag_without_the_default_topics_points_at_the_bag_and_one_with_them_plans(tmp_path):
    from tests.pilotlab.data.bagfiles import RawBag, drive_bag, images
    drive_bag(tmp_path / "run.bag", "ros1", images(3))
    text = RECIPE.replace("train: {record: {circuits: [simple_circuit],", BAG_DATASET % "")
    assert any(job.kind == "frames" and "run.bag" in job.name for job in engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN))
    (tmp_path / "run.bag").unlink()
    with RawBag(tmp_path / "run.bag", "ros1") as bag:
        bag.twist(10**9, 1.0, 0.0, topic="/cmd_vel")
    with pytest.raises(RecipeError, match=r":3: datasets\.train\.bags\.0: bag run\.bag: none of the default image "
                                          r"topics \(/F1ROS/.*\) and no command topic '/F1ROS/cmd_vel'; topics "
                                          r"present: /cmd_vel \(geometry_msgs/msg/Twist\)"):
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)


def test_a_damaged_bag_is_left_to_the_frames_job_that_says_how(tmp_path):
    (tmp_path / "run.bag").write_bytes(b"#ROSBAG V2.0\n" + b"\0" * 100)
    text = RECIPE.replace("train: {record: {circuits: [simple_circuit],", BAG_DATASET % "")
    assert any("run.bag" in job.name for job in engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN))


def test_a_recipe_without_a_test_set_is_told_what_one_is_for_at_its_datasets(tmp_path):
    """outside test: the error named `offline.data`, a key the recipe did not have, at line 1, with no fix."""
    text = "\n".join(line for line in RECIPE.splitlines() if not line.startswith("  test:")) + "\n"
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, text), DOMAIN)
    message = str(caught.value)
    assert ":2: datasets: the offline evaluation (MSE, size, timing) needs a test set, and dataset 'test' is not " \
           "defined (datasets: train); add one, e.g. `test: {record:" in message and "offline: {data: NAME}" in message
    named = text.replace("matrix:", "offline: {data: spare}\nmatrix:")
    with pytest.raises(RecipeError, match=r":\d+: offline\.data: dataset 'spare' is not defined; datasets: train"):
        engine.plan_jobs(recipe_at(tmp_path, named), DOMAIN)


@pytest.mark.parametrize("old, new, where", [
    ("circuit: [simple_circuit]", "circuit: [circuits/nope.csv]", ":15: matrix.circuit"),
    ("train: {record: {circuits: [simple_circuit]", "train: {record: {circuits: [data/nope.csv]",
     ":3: datasets.train.record.circuits"),
])
def test_a_circuit_path_that_names_no_file_says_where_it_was_looked_for(tmp_path, old, new, where):
    """outside test: `unknown circuit 'data/nope.csv'; ... or give the path of a CSV` to a user who gave one."""
    with pytest.raises(RecipeError) as caught:
        engine.plan_jobs(recipe_at(tmp_path, RECIPE.replace(old, new)), DOMAIN)
    name = new.split("[")[-1].rstrip("]")
    assert f"{where}: circuit {name!r}: no such CSV file (looked for {tmp_path / name})" in str(caught.value)


def test_the_run_says_how_many_timings_stayed_disturbed_and_how_to_measure_them_again(tmp_path):
    """Outside test: a run whose every timing stayed disturbed ended "done: 24 ok", the report alone said so."""
    from types import SimpleNamespace
    from pilotlab.domain import unstable_line
    recipe = recipe_at(tmp_path)
    jobs = engine.plan_jobs(recipe, DOMAIN)
    timings = [job for job in jobs if job.kind == "timing"]
    disturbed = {timings[0].key, timings[1].key}
    results = {job.key: {"status": "ok", "value": {"unstable": {"latency_ms": "busy"}} if job.key in disturbed else {}}
               for job in jobs}
    plan = SimpleNamespace(statuses=[SimpleNamespace(job=job) for job in jobs])
    store = SimpleNamespace(result=results.get)
    assert unstable_line(recipe, plan, store) == (
        f"⚠ 2 of {len(timings)} timings stayed disturbed (the machine was busy while they were measured): the report "
        f"marks them, with each one's reason, and draws no conclusion from them; on a quiet machine, `pilotlab run "
        f"{recipe.file} --force timing` measures them again")
    assert unstable_line(recipe, plan, SimpleNamespace(result=lambda key: None)) is None
