"""Benchmark: batch-1 latency of issue 24's strategies as ratios to fp32 eager (the baseline), all from one
run: the TF-MOT rows on LiteRT (pilotlab/strategies/mot.py), with litert and litert_int8 beside them for
reference, and the pruned networks with their stem subsampled (pilotlab/strategies/stem.py) on ONNX Runtime
fp32 and int8 and on LiteRT int8; plus each artifact's raw and gzip-compressed size.

The strategies are built without fine-tuning (the masks, clusters and int8 grids are in the weights
all the same; timings do not depend on what the weights learnt). Variants are interleaved (each
round times every variant in a fresh random order), so load from other processes spreads over all
of them; the spread (min–max over rounds) is printed, and with one thread the calling thread's CPU
time per call too (what the scheduler gave to other processes does not count).
Run: PYTHONPATH=. python -m pytest -m benchmark -s tests/pilotlab/strategies/test_mot_benchmark.py
(PILOTLAB_BENCH_ROUNDS=N rounds, default 5). Never asserts timings (the machine is shared).
"""
from __future__ import annotations

import os
import random
import statistics
import time

import pytest

from matrix.kinds import NotApplicable
from pilotlab.hardware import apply_profile, describe_host, host_fingerprint, make_profile
from pilotlab.offline import TimingSettings, measure_latency, sample_batch
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy
from tests.pilotlab.conftest import random_frames

ROUNDS = int(os.environ.get("PILOTLAB_BENCH_ROUNDS", "5"))
NO_TRAINING = {"finetune_epochs": 0, "qat_epochs": 0, "calibration_frames": 64}
OPTIONS = {"baseline": {}, "litert": {}, "litert_int8": {"calibration_frames": 64},
           "prune_litert": {"finetune_epochs": 0}, "prune_litert_int8": {"finetune_epochs": 0, "calibration_frames": 64},
           "qat_litert_int8": {"qat_epochs": 0, "calibration_frames": 64}, "pqat_litert_int8": NO_TRAINING,
           "cqat_litert_int8": NO_TRAINING, "pcqat_litert_int8": {**NO_TRAINING, "cluster_epochs": 0}}
STEM = {"amount": 0.65, "subsample_stem": 2, "finetune_epochs": 0}       # the study recipe's, untrained
VARIANTS = {**{name: (name, options) for name, options in OPTIONS.items()},
            "stem2 onnx fp32": ("structured_prune", {**STEM, "format": "onnx"}),
            "stem2 onnx int8": ("structured_prune_int8", {**STEM, "calibration_frames": 64}),
            "stem2 litert int8": ("structured_prune_litert_int8", {**STEM, "calibration_frames": 64})}
TIMING = TimingSettings(warmup_runs=20, warmup_seconds=0.1, min_runs=200, max_seconds=0.6, block_seconds=0.1,
                        min_blocks=3, stable_within=0.0)


def cpu_ms(predict, batch, runs: int = 200) -> float:
    """Median CPU time of the calling thread per call (ms): with one thread, the work itself."""
    times = []
    for _ in range(runs):
        start = time.thread_time_ns()
        predict(batch)
        times.append(time.thread_time_ns() - start)
    return statistics.median(times) / 1e6


@pytest.mark.benchmark
def test_benchmark_the_tfmot_strategies(trained, tmp_path):
    frames = tmp_path / "frames"
    random_frames(128, seed=3).save(frames)
    built = {}
    for name, (strategy, options) in VARIANTS.items():
        folder = tmp_path / name.replace(" ", "_")
        try:
            built[name] = {**apply_strategy(strategy, options, StrategySource(trained / "model.pt", folder, (frames,))),
                           "folder": folder}
        except NotApplicable as reason:
            print(f"{name}: not applicable: {reason}")
    profile = make_profile("cpu1")
    apply_profile(profile)
    predictors = {name: load_predictor(built[name]["folder"], profile) for name in built}
    one = sample_batch(random_frames(8, seed=4), 1, 1)
    rounds = []
    for _ in range(ROUNDS):
        figures = {}
        for name in random.sample(list(predictors), len(predictors)):
            figures[name] = (measure_latency(predictors[name].predict, one, TIMING)["latency_ms"],
                             cpu_ms(predictors[name].predict, one))
        rounds.append(figures)
    print(f"\nhost: {describe_host(host_fingerprint())}; load average {os.getloadavg()}")
    print(f"== cpu1 (1 thread), {ROUNDS} interleaved rounds; ×eager = fp32 eager (baseline) / this ==")
    print(f"{'strategy':20} {'b1 ms':>7} {'spread':>15} {'×eager':>7} {'CPU ms':>7} {'×eager':>7} {'MB':>6} {'gzip MB':>8}")
    for name in sorted(predictors, key=lambda n: statistics.median(r[n][0] for r in rounds)):
        wall = [r[name][0] for r in rounds]
        print(f"{name:20} {statistics.median(wall):7.3f} {min(wall):7.3f}–{max(wall):<7.3f} "
              f"{statistics.median(r['baseline'][0] / r[name][0] for r in rounds):7.2f} "
              f"{statistics.median(r[name][1] for r in rounds):7.3f} "
              f"{statistics.median(r['baseline'][1] / r[name][1] for r in rounds):7.2f} "
              f"{built[name]['size_mb']:6.2f} {built[name]['size_gz_mb']:8.2f}")
