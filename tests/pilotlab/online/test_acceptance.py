"""Issue 6's acceptance, end to end through the job handlers (slow: about a minute and a half on 2 cores):
the expert records simple_circuit both ways with swerves (recoveries), PilotNet trains on it, the
`baseline` strategy packs it, the `timing` job times it on cpu1, and the `online` job drives it,
replaying those timings (the default timing mode, as a recipe wires it).

- the trained baseline completes simple_circuit; the metrics and the trajectory picture are in the result;
- with 100 ms more latency the brain runs at 10 Hz or less and drives worse (or fails the lap);
- repetitions from three start points give a mean and a spread.

`pytest -m benchmark -s tests/pilotlab/online/test_acceptance.py` prints the figures for 0-200 ms of
added latency (it trains its own network first).
"""
from __future__ import annotations

import json

import pytest
import torch

import pilotlab.jobs.frames  # noqa: F401  (register the kinds)
import pilotlab.jobs.online  # noqa: F401
import pilotlab.jobs.optimize  # noqa: F401
import pilotlab.jobs.record  # noqa: F401
import pilotlab.jobs.timing  # noqa: F401
import pilotlab.jobs.train  # noqa: F401
from matrix.kinds import KINDS, DepResult
from pilotlab.report import pick_metrics
from tests.pilotlab.jobs.context import context, finished

RECORDINGS = [("cw", 0), ("ccw", 1)]
TRAIN = {"epochs": 12, "batch_size": 64, "lr": 1e-3, "patience": None, "val_fraction": 0.1, "val_by": "block",
         "augment": {"flip": True}}
CPU1 = {"name": "cpu1", "threads": 1}
ONLINE = {"circuit": "simple_circuit", "hardware": CPU1, "camera_frames": 4}
QUICK_TIMING = {"max_seconds": 1.0, "throughput_seconds": 0.3}


def run_job(tmp_path, kind: str, name: str, params: dict, deps=None, inputs=None) -> DepResult:
    ctx = context(tmp_path, kind, name, params, deps=deps, inputs=inputs)
    result = KINDS.get(kind).handler(ctx)
    json.dumps(result)
    return finished(ctx, result)


@pytest.fixture(scope="module")
def artifact(tmp_path_factory) -> dict[str, DepResult]:
    """record (x2) -> frames (x2) -> train -> optimize baseline -> timing on cpu1: the online job's
    `artifact` and `timing` dependencies."""
    torch.set_num_threads(2)
    root = tmp_path_factory.mktemp("acceptance")
    frames = []
    for direction, seed in RECORDINGS:
        bag = run_job(root, "record", f"record-{direction}", {"circuit": "simple_circuit", "direction": direction,
                                                               "seed": seed, "noise": 0.1, "compressed": "png"})
        frames.append(run_job(root, "frames", f"frames-{direction}", {}, deps={"bag": bag}))
    model = run_job(root, "train", "train", TRAIN, deps={"frames": tuple(frames)})
    print(f"\ntrained PilotNet: val_mse {model.result['val_mse']:.4f} "
          f"(mean predictor {model.result['val_mse_mean_predictor']:.4f}) in {model.result['seconds']:.0f} s")
    optimized = run_job(root, "optimize", "optimize", {"strategy": "baseline"}, deps={"model": model})
    timed = run_job(root, "timing", "timing", {"hardware": CPU1, "timing": QUICK_TIMING},
                    deps={"artifact": optimized, "frames": tuple(frames)})
    print(f"baseline on cpu1: {timed.result['latency_ms']:.2f} ms per frame (replayed by the laps)")
    return {"artifact": optimized, "timing": timed}


def drive(tmp_path, artifact: dict[str, DepResult], name: str, **params) -> tuple[dict, object]:
    online = run_job(tmp_path, "online", name, {**ONLINE, **params}, deps=artifact)
    result = online.result
    print(f"\n{name}: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                   for k, v in pick_metrics(result).items()))
    return result, online.artifacts


@pytest.mark.slow
def test_a_trained_pilotnet_completes_simple_circuit_and_latency_matters(tmp_path, artifact):
    result, folder = drive(tmp_path, artifact, "online-baseline")
    assert result["lap_completed"] is True and result["runs"][0]["termination"] == "lap_completed"
    assert result["position_deviation_mae_m"] < 0.5 and result["off_road_events"] == 0
    assert result["brain_frequency_sim_hz"] > 15
    assert (folder / result["trajectory"]).stat().st_size > 10_000 and len(result["camera_frames"]) == 4

    late, _ = drive(tmp_path, artifact, "online-plus-100ms", extra_latency_ms=100.0)
    assert late["brain_frequency_sim_hz"] <= 10.0
    assert (not late["lap_completed"]) or late["position_deviation_mae_m"] > result["position_deviation_mae_m"]


@pytest.mark.slow
def test_repetitions_from_different_start_points_give_mean_and_spread(tmp_path, artifact):
    result, _ = drive(tmp_path, artifact, "online-three-starts", repetitions=3)
    starts = [run["start_m"] for run in result["runs"]]
    assert len(set(starts)) == 3 and result["repetitions"] == 3
    spread = result["spread"]["position_deviation_mae_m"]
    assert spread["runs"] == 3 and spread["min"] <= result["position_deviation_mae_m"] <= spread["max"]
    assert spread["std"] > 0
    assert result["spread"]["lap_completed"] == {"completed": 3, "runs": 3}


@pytest.mark.slow
@pytest.mark.benchmark
def test_latency_sweep(tmp_path, artifact):
    rows = []
    for extra in (0.0, 50.0, 100.0, 150.0, 200.0):
        result, _ = drive(tmp_path, artifact, f"online-{extra:g}ms", extra_latency_ms=extra)
        rows.append((extra, result))
        assert result["brain_frequency_sim_hz"] <= 1000 / max(50.0, extra)
    print("\nadded latency | lap | lap s | % done | avg speed | deviation MAE m | brain Hz (sim) | suddenness")
    for extra, r in rows:
        print(f"{extra:13g} | {r['lap_completed']!s:5} | {r.get('lap_seconds', float('nan')):5.1f} | "
              f"{r['percentage_completed']:6.1f} | {r['average_speed']:9.2f} | {r['position_deviation_mae_m']:15.3f} | "
              f"{r['brain_frequency_sim_hz']:14.1f} | {r['suddenness']:.3f}")
