"""Recipes with models the user brings (network / weights / torchscript / onnx): planning, the
job keys (editing the network file reruns exactly that model's jobs), and recipe errors with the
file, line and key. Planning reads the user's files; it never runs them."""
from __future__ import annotations

from pathlib import Path

import pytest

from matrix import RecipeError, engine
from matrix.recipe import load_recipe
from pilotlab.domain import DOMAIN
from tests.pilotlab.models.user_networks import DLS_PILOTNET, write

RECIPE = """\
name: own
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.1}}
  test: {record: {circuits: [simple_circuit], laps: 0.1, seed: 2}}
models:
  builtin: {arch: pilotnet, epochs: 1}
  dls: {network: nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2}, preset: dls,
        epochs: 1}
  frozen: {network: nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2},
           weights: weights/dls.pth, train: false, preset: dls}
  graph: {onnx: models/pilotnet.onnx, preset: dls}
matrix:
  model: [builtin, dls, frozen, graph]
  strategy: [baseline, dynamic_quant]
  hardware: [cpu]
  circuit: [simple_circuit]
"""


@pytest.fixture
def folder(tmp_path) -> Path:
    write(tmp_path, "nets/pilotnet.py", "from layers import relu_stack  # noqa\n" + DLS_PILOTNET)
    write(tmp_path, "nets/layers.py", "def relu_stack():\n    return None\n")
    write(tmp_path, "weights/dls.pth", "state dict bytes")     # planning hashes files, never loads them
    write(tmp_path, "models/pilotnet.onnx", "onnx bytes")
    return tmp_path


def plan(folder: Path, text: str = RECIPE) -> dict:
    path = folder / "own.yaml"
    path.write_text(text)
    return {job.name: job for job in engine.plan_jobs(load_recipe(path, DOMAIN), DOMAIN)}


def keys(folder: Path) -> dict[str, str]:
    return {name: job.key for name, job in plan(folder).items()}


def test_a_model_used_as_it_is_runs_beside_other_jobs_a_training_alone(folder):
    """Outside test: a weights-only model (2.8 s of loading) waited minutes for the host like a training."""
    from matrix.kinds import KINDS
    alone = {name for name, job in plan(folder).items() if job.kind == "train" and KINDS.get("train").runs_alone(job.params)}
    assert alone == {"train builtin", "train dls"}   # frozen (train: false) and graph (onnx) are used as they are


def of_model(model: str, names) -> set[str]:
    return {n for n in names if n == f"train {model}" or f" {model}/" in n}


def test_the_models_files_are_the_train_jobs_inputs(folder):
    jobs = plan(folder)
    assert set(jobs["train dls"].inputs) == {"network_source"}
    assert set(jobs["train frozen"].inputs) == {"network_source", "weights"}
    assert set(jobs["train graph"].inputs) == {"onnx"}
    assert jobs["train dls"].params["network"] == "nets/pilotnet.py:PilotNet"   # as written: the key is portable
    assert jobs["train dls"].params["labels"] == {"v": [6.5, 24.0], "w": [-7.1, 7.1]}   # the dls preset
    # the dls preset's preprocessing: its own frames jobs, for training and for the test set
    frames = [job for job in jobs.values() if job.kind == "frames"]
    assert sorted(job.params["interpolation"] for job in frames) == ["fast_area", "fast_area", "linear", "linear"]
    assert {dep.params["interpolation"] for dep in jobs["offline dls/baseline on cpu"].deps["test"]} == {"linear"}


@pytest.mark.parametrize("edited, models", [("nets/pilotnet.py", {"dls", "frozen"}),
                                            ("nets/layers.py", {"dls", "frozen"}),   # a module it imports
                                            ("weights/dls.pth", {"frozen"}),
                                            ("models/pilotnet.onnx", {"graph"})])
def test_editing_a_models_file_reruns_exactly_that_models_jobs(folder, edited, models):
    before = keys(folder)
    (folder / edited).write_text((folder / edited).read_text() + ("\n_EDITED = 1\n" if edited.endswith(".py") else "\n# an edit\n"))
    after = keys(folder)
    assert after.keys() == before.keys()
    changed = {name for name in after if after[name] != before[name]}
    assert changed == set().union(*(of_model(m, before) for m in models))


def test_plan_names_the_module_that_changed_among_a_networks_imports(folder):
    """The network's input hash covers the modules it imports; `plan`'s reason names the one edited (it
    named the network's own file, whichever had changed)."""
    from matrix.stale import own_changes
    before = plan(folder)["train dls"].spec()
    assert before["inputs"]["network_source"]["parts"].keys() == {"nets/pilotnet.py", "nets/layers.py"}
    (folder / "nets/layers.py").write_text((folder / "nets/layers.py").read_text() + "\n_EDITED = 1\n")
    assert own_changes(plan(folder)["train dls"], before) == ["input changed: network_source (nets/layers.py)"]


def test_onnx_external_data_is_an_input_resolved_beside_the_model(folder, monkeypatch):
    import torch
    from tests.pilotlab.models.test_user_models import onnx_with_external_data
    from tests.pilotlab.models.user_networks import DLS_OPTIONS, load_class
    torch.manual_seed(5)
    net = load_class(write(folder, "plain/pilotnet.py", DLS_PILOTNET), "PilotNet")(**DLS_OPTIONS).eval()
    onnx_with_external_data(folder, net)                     # models/m.onnx + models/sub/local.bin
    (folder / "models/pilotnet.onnx").write_bytes((folder / "models/m.onnx").read_bytes())
    monkeypatch.chdir(folder / "nets")                       # planned from another folder
    jobs = plan(folder)
    data = jobs["train graph"].inputs["onnx data sub/local.bin"]
    assert Path(data.path) == folder / "models/sub/local.bin"
    before = keys(folder)
    with open(folder / "models/sub/local.bin", "ab") as weights:
        weights.write(b"\x00\x00\x80\x3f")               # an edit (a size change, whatever the clock's tick)
    after = keys(folder)
    assert {name for name in after if after[name] != before[name]} == of_model("graph", before)


def test_onnx_external_data_outside_the_models_folder_is_a_recipe_error(folder):
    import onnx
    from onnx import TensorProto, helper, numpy_helper
    import numpy as np
    bias = numpy_helper.from_array(np.zeros((1, 2), np.float32), "bias")
    bias.ClearField("raw_data")
    bias.data_location = TensorProto.EXTERNAL
    for key, value in (("location", "../../secret.bin"), ("offset", "0"), ("length", "8")):
        bias.external_data.add(key=key, value=value)
    graph = helper.make_graph([helper.make_node("Add", ["x", "bias"], ["y"])], "g",
                              [helper.make_tensor_value_info("x", TensorProto.FLOAT, [None, 2])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, None)], [bias])
    onnx.save(helper.make_model(graph), str(folder / "models/pilotnet.onnx"))
    message = recipe_error(folder, "", "")
    assert "models.graph.onnx" in message and "'../../secret.bin', outside the model file's folder" in message


def recipe_error(folder: Path, old: str, new: str) -> str:
    with pytest.raises(RecipeError) as caught:
        plan(folder, RECIPE.replace(old, new))
    message = str(caught.value)
    assert "\n" not in message and "own.yaml" in message
    return message


def test_a_missing_file_names_the_key(folder):
    message = recipe_error(folder, "weights/dls.pth", "weights/gone.pth")
    assert "models.frozen.weights" in message and "weights/gone.pth does not exist" in message
    message = recipe_error(folder, "nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2}, "
                                   "preset", "nets/missing.py:PilotNet, preset")
    assert "models.dls.network" in message and "nets/missing.py: no such file" in message


def test_a_syntax_error_names_the_key_and_the_line(folder):
    write(folder, "nets/pilotnet.py", "import torch\n\nclass PilotNet(\n")
    message = recipe_error(folder, "", "")
    assert "models.dls.network" in message and "pilotnet.py:3: syntax error" in message


@pytest.mark.parametrize("old, new, said", [
    ("dls: {network: nets/pilotnet.py:PilotNet,", "dls: {network: nets/pilotnet.py:PilotNt,",
     "models.dls.network: {folder}/nets/pilotnet.py has no 'PilotNt' (did you mean 'PilotNet'?); it defines: PilotNet"),
    ("options: {image_shape: [200, 66, 3], num_labels: 2}, preset: dls,\n        epochs",
     "options: {image_shap: [200, 66, 3], num_labels: 2}, preset: dls,\n        epochs",
     "models.dls.network: options: PilotNet(image_shape, num_labels) does not take image_shap (did you mean "
     "'image_shape'?)"),
    ("options: {image_shape: [200, 66, 3], num_labels: 2}, preset: dls,\n        epochs",
     "options: {num_labels: 2}, preset: dls,\n        epochs",
     "models.dls.network: options: PilotNet(image_shape, num_labels) needs image_shape, which has no default: "
     "give it under options"),
])
def test_a_class_or_option_the_source_lacks_fails_the_plan(folder, old, new, said):
    """Outside test: a typo'd class or option planned, then failed its train job in the run."""
    assert said.format(folder=folder) in recipe_error(folder, old, new)


def test_what_the_source_cannot_say_is_left_to_loading(folder):
    write(folder, "nets/star.py", "from torch.nn import *\n")
    write(folder, "nets/wide.py", "import torch\nclass Net(torch.nn.Module):\n    def __init__(self, **options):\n"
                                  "        super().__init__()\n")
    text = RECIPE.replace("nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2}, preset: dls,\n"
                          "        epochs", "nets/star.py:Linear, options: {in_features: 2}, preset: dls,\n        epochs")
    text = text.replace("frozen: {network: nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2}",
                        "frozen: {network: nets/wide.py:Net, options: {anything: 1}")
    assert "train dls" in plan(folder, text) and "optimize frozen/baseline" in plan(folder, text)


@pytest.mark.parametrize("old, new, said", [
    ("graph: {onnx: models/pilotnet.onnx,", "graph: {onnx: models/pilotnet.onnx, arch: pilotnet,",
     "give one of arch, network, torchscript, onnx, not arch and onnx"),
    ("weights: weights/dls.pth, train: false", "train: false", "train: false needs `weights:`"),
    ("preset: dls}\n  graph", "}\n  graph", "labels: a model used as it is needs the label ranges it was trained with"),
    ("graph: {onnx: models/pilotnet.onnx,", "graph: {onnx: models/pilotnet.onnx, train: true,",
     "onnx models are used as they are"),
    ("builtin: {arch: pilotnet", "builtin: {arch: network", "arch 'network' names checkpoints of models you bring"),
    ("preset: dls", "preset: bls", "preset"),
    # outside test: "String should match pattern '.:[A-Za-z_][\\w.]*$'"
    ("dls: {network: nets/pilotnet.py:PilotNet,", "dls: {network: nets/pilotnet.py,",
     "'nets/pilotnet.py': name your code as file.py:Class or module:Class (the class after a colon)"),
])
def test_inconsistent_model_entries(folder, old, new, said):
    message = recipe_error(folder, old, new)
    assert said in message and "models." in message
