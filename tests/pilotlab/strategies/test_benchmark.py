"""Benchmark: PilotNet batch-1 latency and batch-64 throughput of every strategy, as ratios to fp32
eager measured in the same run, per thread count; plus pilotlab's timing against a bare loop.

Variants are interleaved (each round measures every variant in a fresh random order) and rounds
repeat, so load from other processes spreads over all variants; the spread (min–max over rounds)
is printed. Run: PYTHONPATH=. python -m pytest -m benchmark -s tests/pilotlab/strategies/test_benchmark.py
Never asserts timings (the machine is shared).
"""
from __future__ import annotations

import os
import random
import statistics
import time

import numpy as np
import pytest

from matrix.kinds import NotApplicable
from pilotlab.hardware import apply_profile, cpu_count, describe_host, host_fingerprint, make_profile
from pilotlab.offline import TimingSettings, measure_latency, measure_throughput, sample_batch
from pilotlab.predictor import OnnxPredictor, TorchPredictor, load_predictor
from pilotlab.strategies import STRATEGIES, StrategySource, apply_strategy
from tests.pilotlab.conftest import random_frames

ROUNDS = int(os.environ.get("PILOTLAB_BENCH_ROUNDS", "5"))
ROUND_TIMING = TimingSettings(warmup_runs=20, warmup_seconds=0.1, min_runs=200, max_seconds=0.6,
                              block=100, stable_within=0.0, throughput_batch=64, throughput_seconds=0.4)
NO_FINETUNE = {name: {"finetune_epochs": 0} for name in
               ("local_prune", "global_prune", "structured_prune", "cluster", "qat", "prune_quant")}


def build_all(trained, frames, root) -> tuple[dict, dict]:
    built, skipped = {}, {}
    for name in STRATEGIES:
        try:
            apply_strategy(name, NO_FINETUNE.get(name, {}), StrategySource(trained / "model.pt", root / name, (frames,)))
            built[name] = root / name
        except NotApplicable as reason:
            skipped[name] = str(reason)
    return built, skipped


def bare_call(predictor, batch: np.ndarray):
    """A call straight to the runtime, as a hand-written loop would make it."""
    if isinstance(predictor, OnnxPredictor):
        run, feed = predictor.session.run, {"images": batch}
        return lambda: run(["vw"], feed)
    import torch
    module, tensor = predictor._module, torch.from_numpy(batch)

    def call():
        with torch.inference_mode():
            return module(tensor)
    return call


def bare_loop(call, runs: int = 300) -> list[float]:
    """The simplest per-call timing loop (ms), after a warm-up."""
    for _ in range(30):
        call()
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        call()
        times.append((time.perf_counter() - start) * 1e3)
    return times


def measure_round(predictors, profile, one, many) -> dict:
    figures = {}
    for name in random.sample(list(predictors), len(predictors)):
        apply_profile(profile)
        predictor = predictors[name]
        latency = measure_latency(predictor.predict, one, ROUND_TIMING)["latency_ms"]
        throughput = measure_throughput(predictor, many, ROUND_TIMING)["throughput_ips"]
        figures[name] = (latency, throughput)
    return figures


def print_table(profile, rounds: list[dict]) -> None:
    names = sorted(rounds[0], key=lambda n: statistics.median(r[n][0] for r in rounds))
    print(f"\n== {profile.name}: {profile.cpu_threads} thread(s), {len(rounds)} interleaved rounds ==")
    print(f"{'strategy':18} {'b1 ms':>8} {'spread':>15} {'×eager':>7} {'b64 img/s':>10} {'spread':>17} {'×eager':>7}")
    for name in names:
        lat = [r[name][0] for r in rounds]
        ips = [r[name][1] for r in rounds]
        speedup = statistics.median(r["baseline"][0] / r[name][0] for r in rounds)
        gain = statistics.median(r[name][1] / r["baseline"][1] for r in rounds)
        print(f"{name:18} {statistics.median(lat):8.3f} {min(lat):7.3f}–{max(lat):<7.3f} {speedup:7.2f} "
              f"{statistics.median(ips):10.0f} {min(ips):8.0f}–{max(ips):<8.0f} {gain:7.2f}")


def overhead(predictors, profile, one) -> None:
    """pilotlab's latency (Predictor.predict timed by offline.measure_latency) against a bare loop
    timing the runtime call of the same artifact; alternating blocks, medians compared."""
    print(f"\n-- pilotlab timing vs a bare loop ({profile.name}), {2 * ROUNDS} alternating blocks --")
    settings = TimingSettings(warmup_runs=30, warmup_seconds=0.0, min_runs=300, max_runs=300, block=300)
    for name in ("baseline", "torchscript", "onnxruntime", "onnxruntime_int8"):
        apply_profile(profile)
        call, ours, bare = bare_call(predictors[name], one), [], []
        for _ in range(2 * ROUNDS):
            bare.append(statistics.median(bare_loop(call)))
            ours.append(measure_latency(predictors[name].predict, one, settings)["latency_ms"])
        ratios = [o / b for o, b in zip(ours, bare)]
        print(f"{name:18} pilotlab {statistics.median(ours):.4f} ms  bare {statistics.median(bare):.4f} ms  "
              f"ratio {statistics.median(ratios):.3f} (spread {min(ratios):.3f}–{max(ratios):.3f})")


@pytest.mark.benchmark
def test_benchmark_every_strategy(trained, tmp_path):
    frames = tmp_path / "frames"
    random_frames(256, seed=3).save(frames)
    built, skipped = build_all(trained, frames, tmp_path / "artifacts")
    test = random_frames(64, seed=4)
    one, many = sample_batch(test, 1, 1), sample_batch(test, 64, 1)
    print(f"\nhost: {describe_host(host_fingerprint())}; load average before: {os.getloadavg()}")
    for name, reason in skipped.items():
        print(f"{name}: not applicable: {reason}")
    for profile in (make_profile("cpu1"), make_profile("cpu")) if cpu_count() > 1 else (make_profile("cpu1"),):
        predictors = {name: load_predictor(folder, profile) for name, folder in built.items()}
        rounds = [measure_round(predictors, profile, one, many) for _ in range(ROUNDS)]
        print_table(profile, rounds)
        overhead(predictors, profile, one)
        del predictors
    print(f"load average after: {os.getloadavg()}")
