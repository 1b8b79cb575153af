"""The whole pipeline's figures from one run: `python -m pytest -m benchmark -s tests/pilotlab/test_pipeline_benchmark.py`.

Prints (never asserts timings; issue 17's table):
- the simulator's real-time factor on an expert lap of simple_circuit: without a camera, with the
  640×480 camera the record job uses then preprocessing (the online path before the network view),
  and with the network's view rendered directly (the online path now);
- `pilotlab plan` of a recipe of ~9,000 jobs generated here (table and --json);
- a cold run of the quickstart (default -j: one job per core) with its time per job kind;
- network laps of the quickstart's networks (int8 ones included) with the view and with the full frame.
Wall-clock figures follow the host's load (printed with them); CPU-time real-time factors less so.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.child import python_path

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.benchmark


def load() -> str:
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} cores"


def cli(*args: str, cwd: Path) -> tuple[float, subprocess.CompletedProcess]:
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pilotlab", *args], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": python_path(ROOT)})
    assert done.returncode == 0, done.stderr[-2000:]
    return time.perf_counter() - started, done


def expert_lap(camera: str, expert_config=None, **place) -> tuple[float, float, float, str]:
    """(simulated s, wall s, CPU s, termination) of the expert's lap, a frame every step: of simple_circuit,
    or where `place` says (world=, assets= for a BM world, with its `expert_config`)."""
    import cv2

    from pilotlab.data.preprocess import PreprocessConfig, preprocess
    from pilotlab.sim.camera import CameraSpec
    from pilotlab.sim.env import DrivingEnv
    from pilotlab.sim.expert import Expert, ExpertConfig
    cv2.setNumThreads(1)
    config = PreprocessConfig()
    with DrivingEnv(**(place or {"circuit": "simple_circuit"}), camera=None if camera == "none" else CameraSpec(),
                    renderer="ground", view=config if camera == "view" else None) as env:
        obs, info = env.reset(seed=0)
        expert = Expert(env.circuit, expert_config or ExpertConfig())
        env.step(expert.act(info))            # builds the ground raster (or reads the world) outside the timing
        obs, info = env.reset(seed=0)
        wall, cpu = time.perf_counter(), time.process_time()
        while True:
            obs, _, terminated, truncated, info = env.step(expert.act(info), render=camera != "none")
            if camera == "full":
                preprocess(obs, config)       # what the network brain did with the full frame
            if terminated or truncated:
                break
        return info["sim_time"], time.perf_counter() - wall, time.process_time() - cpu, info["termination"]


def test_simulator_real_time_factor():
    print(f"\nexpert lap of simple_circuit at 20 Hz, one frame per step ({load()}):")
    for camera, label in (("none", "no camera"), ("full", "640x480 frame, then preprocess"),
                          ("view", "network view rendered directly")):
        sim, wall, cpu, termination = expert_lap(camera)
        print(f"  {label:32s}: real-time factor {sim / wall:6.1f}x wall, {sim / cpu:6.1f}x CPU ({termination})")


def big_recipe(path: Path, aliases: int = 100) -> Path:
    """2 models × `aliases` local_prune aliases × 4 hardware profiles × 5 circuits × 2 directions."""
    lines = ["name: big_plan", "datasets:",
             "  train: {record: {circuits: [many_curves, nurburgring], directions: [cw, ccw], laps: 1}}",
             "  test: {record: {circuits: [simple_circuit], laps: 0.5, seed: 2}}",
             "models:", "  pilotnet: {arch: pilotnet, epochs: 2}", "  pilotnet_b: {arch: pilotnet, epochs: 2, seed: 1}",
             "strategies:"]
    lines += [f"  prune{i}: {{use: local_prune, conv: {i / 200:.3f}, linear: {i / 150:.3f}}}" for i in range(aliases)]
    lines += ["hardware:", "  cpu2: {device: cpu, threads: 2}", "  cpu3: {device: cpu, threads: 3}",
              "online: {directions: [cw, ccw]}", "matrix:", "  model: [pilotnet, pilotnet_b]",
              f"  strategy: [{', '.join(f'prune{i}' for i in range(aliases))}]", "  hardware: [cpu, cpu1, cpu2, cpu3]",
              "  circuit: [simple_circuit, many_curves, montmelo, montreal, nurburgring]"]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_plan_of_nine_thousand_jobs(tmp_path):
    import json
    recipe = big_recipe(tmp_path / "big.yaml")
    store = str(tmp_path / "store")
    as_json, done = cli("plan", str(recipe), "--json", "--store", store, cwd=tmp_path)
    jobs = len(json.loads(done.stdout))
    table, done = cli("plan", str(recipe), "--store", store, cwd=tmp_path)
    print(f"\n`pilotlab plan` of {jobs} jobs ({load()}): table {table:.2f} s (target < 3 s), --json {as_json:.2f} s "
          f"(target < 2 s), start-up included; the table printed {len(done.stdout.splitlines())} lines")


@pytest.fixture(scope="module")
def quickstart(tmp_path_factory) -> tuple[Path, float]:
    """A cold run of the quickstart recipe in a fresh store (its report goes to the temporary folder)."""
    folder = tmp_path_factory.mktemp("quickstart")
    shutil.copy(ROOT / "recipes" / "quickstart.yaml", folder / "quickstart.yaml")
    print(f"\n(cold run of the quickstart starting, {load()})")
    wall, _ = cli("run", "quickstart.yaml", "--store", str(folder / "store"), cwd=folder)
    return folder / "store", wall


def test_quickstart_cold_run_and_time_per_kind(quickstart):
    from matrix.runs import default_jobs
    from matrix.store import Store
    from matrix.times import kind_times, recipe_keys
    store_path, wall = quickstart
    store = Store(store_path)
    rows = kind_times(store, recipe_keys(store, "quickstart"))
    print(f"\nquickstart cold run on {default_jobs()} workers: {wall:.1f} s wall ({load()} after it); job time per kind:")
    for row in rows:
        print(f"  {row.kind:9s} {row.jobs:3d} jobs {row.total_s:7.1f} s (mean {row.mean_s:6.1f} s, "
              f"slowest {row.max_s:6.1f} s: {row.slowest})")


def network_lap(artifacts: Path, view: bool) -> dict:
    import cv2

    from pilotlab.hardware import profile_from_dict
    from pilotlab.online.brains import NetworkBrain
    from pilotlab.online.drive import drive
    from pilotlab.online.evaluate import OnlineSpec, make_env
    from pilotlab.predictor import load_predictor
    profile = profile_from_dict({"name": "cpu1", "device": "cpu", "threads": 1})
    cv2.setNumThreads(1)
    brain = NetworkBrain(load_predictor(artifacts, profile, spin=False))
    spec = OnlineSpec(circuit="simple_circuit", timing="measured")   # timed live, as before replay timing
    with make_env(spec, camera=True, view=brain.view if view else None) as env:
        brain.warm_up()
        cpu = time.process_time()
        meta = drive(env, brain, spec.drive).meta
    return {**meta, "cpu_seconds": time.process_time() - cpu}


def test_network_laps_real_time_factor(quickstart):
    from matrix.store import Store
    store = Store(quickstart[0])
    optimized = {store.spec(k)["name"]: store.job_dir(k) / "artifacts" for k in store.keys()
                 if store.spec(k)["kind"] == "optimize"}
    print(f"\nnetwork laps of simple_circuit, measured timing, 1 thread ({load()}):")
    for name, artifacts in sorted(optimized.items()):
        for view in (True, False):
            lap = network_lap(artifacts, view)
            sim = lap["sim_seconds"]
            print(f"  {name:38s} {'view' if view else 'full frame':10s}: real-time factor "
                  f"{sim / lap['wall_seconds']:5.1f}x wall, {sim / lap['cpu_seconds']:5.1f}x CPU, inference "
                  f"{lap['measured_inference_ms']:.2f} ms, {lap['termination']} after {sim:.1f} s")
