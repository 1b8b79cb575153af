"""Issue 15's acceptance through a recipe: a state dict saved from an independent copy of
DeepLearningStudio's PyTorch PilotNet (tests/pilotlab/models/user_networks.py, written from its
published layer list) goes through `pilotlab run` with `network:` + `weights:` + `preset: dls` and no
pilotlab source change: it is evaluated offline and drives simple_circuit.

The quick test uses the weights as they are (tiny recordings, a short lap); the slow one fine-tunes
them on recordings of simple_circuit and completes a lap."""
from __future__ import annotations

import pytest
import torch

from matrix import engine
from matrix.recipe import load_recipe
from matrix.store import Store
from pilotlab.domain import DOMAIN
from tests.pilotlab.models.user_networks import DLS_OPTIONS, DLS_PILOTNET, load_class, write

QUICK = """\
name: dls-quick
datasets:
  train: {record: {circuits: [simple_circuit], laps: 0.05, camera: {width: 320, height: 240}}}
  test: {record: {circuits: [simple_circuit], laps: 0.05, seed: 2, camera: {width: 320, height: 240}}}
models:
  dls: {network: nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2},
        weights: pilot_net_model_best_123.pth, train: false, preset: dls}
online: {timeout_s: 2, references: [], timing: lockstep, camera: {width: 320, height: 240}, camera_frames: 0}
offline: {batch: 8}
matrix:
  model: [dls]
  strategy: [baseline]
  hardware: [cpu]
  circuit: [simple_circuit]
"""
SLOW = """\
name: dls-fine-tune
datasets:
  train: {record: {circuits: [simple_circuit], directions: [cw, ccw], laps: 1, noise: 0.1, seed: 1}}
  test: {record: {circuits: [simple_circuit], laps: 0.5, seed: 2}}
models:
  # DLS's preprocessing; the label ranges of this simulator's expert (labels: auto): DLS's, for its Gazebo
  # car (w in [-7.1, 7.1]), squeeze this expert's w (about ±1.5 rad/s) into a fifth of the output range
  dls: {network: nets/pilotnet.py:PilotNet, options: {image_shape: [200, 66, 3], num_labels: 2},
        weights: pilot_net_model_best_123.pth, preset: dls, labels: auto, epochs: 20, patience: null,
        val_fraction: 0.1, val_by: block, augment: {flip: true}}
online: {references: [], timing: lockstep}
matrix:
  model: [dls]
  strategy: [baseline]
  hardware: [cpu]
  circuit: [simple_circuit]
"""


def user_folder(tmp_path):
    """What a DLS user has: the class's file and a state dict saved from it (torch.save(state_dict))."""
    net_file = write(tmp_path, "nets/pilotnet.py", DLS_PILOTNET)
    torch.manual_seed(0)
    torch.save(load_class(net_file, "PilotNet")(**DLS_OPTIONS).state_dict(), tmp_path / "pilot_net_model_best_123.pth")
    return tmp_path


def run_recipe(folder, text: str) -> dict[str, dict]:
    """Run the recipe, write its report into folder/reports; the results by job name."""
    from pilotlab.report.recipe import write_recipe_report
    (folder / "recipe.yaml").write_text(text + f"report: {{folder: {folder / 'reports'}}}\n")
    recipe, store = load_recipe(folder / "recipe.yaml", DOMAIN), Store(folder / "store")
    plan = engine.make_plan(recipe, DOMAIN, store)
    summary = engine.run_plan(plan, DOMAIN, store, jobs=1)
    assert not summary.failed, summary.outcomes
    jobs = [status.job for status in plan.statuses]
    write_recipe_report(recipe, store, jobs)
    return {job.name: store.result(job.key) for job in jobs}


@pytest.mark.slow   # a whole recipe, ~22 s; the DLS weights' own path is in models/test_user_models.py
def test_dls_weights_as_they_are_go_through_a_recipe(tmp_path):
    results = run_recipe(user_folder(tmp_path), QUICK)
    train = results["train dls"]["value"]
    assert train["source"]["kind"] == "network" and train["trained"] is False
    assert train["labels"] == {"v": [6.5, 24.0], "w": [-7.1, 7.1]}
    offline = results["offline dls/baseline on cpu"]
    assert offline["status"] == "ok" and offline["value"]["test_frames"] > 0
    lap = results["online dls/baseline on cpu at simple_circuit cw"]
    assert lap["status"] == "ok" and lap["value"]["runs"]
    readme = (tmp_path / "reports" / "dls-quick" / "README.md").read_text()
    digest = train["source"]["sha256"][:12]     # the report names the model's source
    assert f"- **Model dls**: network nets/pilotnet.py:PilotNet (sha256 {digest}), weights " in readme
    assert "used as it is" in readme


@pytest.mark.slow
def test_dls_weights_fine_tuned_complete_a_lap(tmp_path):
    results = run_recipe(user_folder(tmp_path), SLOW)
    train = results["train dls"]["value"]
    print(f"\nfine-tuned DLS PilotNet: val_mse {train['val_mse']:.4f} (mean predictor "
          f"{train['val_mse_mean_predictor']:.4f}), {train['seconds']:.0f} s")
    assert train["trained"] is True and train["source"]["weights_sha256"]
    assert results["offline dls/baseline on cpu"]["status"] == "ok"
    lap = results["online dls/baseline on cpu at simple_circuit cw"]["value"]
    print(f"lap: completed {lap['lap_completed']}, deviation {lap.get('position_deviation_mae_m')}")
    assert lap["lap_completed"] is True
