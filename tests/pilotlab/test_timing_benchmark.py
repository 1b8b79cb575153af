"""Benchmark (issue 25, figures from a busy machine): the cpu1 batch-1 latency of the quickstart's
strategies quiet, then beside two CPU hogs this benchmark starts itself, one run each; it prints the
loaded/quiet ratio of each figure, which clock it was read on (wall, or the thread's CPU time where
the wall clock stayed disturbed) and why. The target is every ratio within 0.8-1.25. Never asserts a timing (the machine is shared): it prints.

The pair is then timed twice more, quiet and loaded in turn, to show what the host's own drift is
worth: on a VM the host changes speed under the guest without any sign inside it (README, "Timings you
can trust on a busy machine"), so the quiet runs' spread (max/min) says how far apart two runs of the
same figure come on a quiet machine, and the ratio of the loaded runs' median to the quiet runs' median
says what the hogs did with that drift mostly cancelled.

Run: PYTHONPATH=. python -m pytest -m benchmark -s tests/pilotlab/test_timing_benchmark.py
(random weights: the latency of a network does not depend on its values; no fine-tuning).
"""
from __future__ import annotations

import os
import subprocess
import sys
from contextlib import contextmanager

import numpy as np
import pytest

from matrix.kinds import NotApplicable
from pilotlab.hardware import apply_profile, make_profile
from pilotlab.offline import TimingSettings, measure_latency, sample_batch
from pilotlab.predictor import load_predictor
from pilotlab.strategies.apply import StrategySource, apply_strategy
from tests.pilotlab.conftest import random_frames

QUICKSTART = ("baseline", "dynamic_quant", "onnxruntime_int8", "structured_prune_int8")
OPTIONS = {"structured_prune_int8": {"finetune_epochs": 0}}
SETTINGS = TimingSettings(warmup_runs=20, warmup_seconds=0.2, max_seconds=2.0, throughput_seconds=0.3)
HOGS = 2
ROUNDS = 3                  # quiet and loaded in turn; the first pair is the target's "one run each"


@contextmanager
def cpu_hogs(count: int):
    """`count` processes that spin on whatever core they get, for the length of the block."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(count)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


def timed(predictor, batch: np.ndarray, profile) -> dict:
    apply_profile(profile)
    result = measure_latency(predictor.predict, batch, SETTINGS, profile)
    return {**result, "clock": "thread CPU" if result.get("cpu_time") else "wall",
            "state": "unstable" if result.get("unstable") else "ok"}


@pytest.mark.benchmark
def test_cpu1_latency_beside_two_hogs_stays_near_the_quiet_figure(trained, tmp_path):
    frames = tmp_path / "frames"
    random_frames(64, seed=3).save(frames)
    profile = make_profile("cpu1")
    batch = sample_batch(random_frames(8, seed=4), 1, 1)
    print(f"\ncpu1 latency quiet, then beside {HOGS} CPU hogs started here (load average before {os.getloadavg()}, "
          f"{os.cpu_count()} cores)")
    print(f"{'strategy':24} {'quiet ms':>9} {'clock':>10} | {'loaded ms':>9} {'clock':>10} {'state':>8} | "
          f"{'ratio':>6} | calls discarded loaded")
    ratios, medians = [], []
    for name in QUICKSTART:
        try:
            apply_strategy(name, OPTIONS.get(name, {}), StrategySource(trained / "model.pt", tmp_path / name, (frames,)))
        except NotApplicable as reason:
            print(f"{name:24} not applicable: {reason}")
            continue
        predictor = load_predictor(tmp_path / name, profile)
        pairs = [quiet_then_loaded(predictor, batch, profile) for _ in range(ROUNDS)]
        quiet, loaded = pairs[0]
        ratio = loaded["latency_ms"] / quiet["latency_ms"]
        ratios.append(ratio)
        print(f"{name:24} {quiet['latency_ms']:9.3f} {quiet['clock']:>10} | {loaded['latency_ms']:9.3f} "
              f"{loaded['clock']:>10} {loaded['state']:>8} | {ratio:6.2f} | {loaded['timing_calls_discarded']}")
        for reason in (loaded.get("cpu_time") or loaded.get("unstable") or {}).values():
            print(f"{'':24} why: {reason}")
        medians.append(_drift_line(name, pairs))
    if ratios:
        inside = sum(0.8 <= r <= 1.25 for r in ratios)
        print(f"{inside} of {len(ratios)} ratios within 0.8-1.25 (target: all); load average after {os.getloadavg()}")
        print(f"median of {ROUNDS} loaded over median of {ROUNDS} quiet, taken in turn: "
              f"{sum(0.8 <= r <= 1.25 for r in medians)} of {len(medians)} within 0.8-1.25")


def quiet_then_loaded(predictor, batch: np.ndarray, profile) -> tuple[dict, dict]:
    quiet = timed(predictor, batch, profile)
    with cpu_hogs(HOGS):
        return quiet, timed(predictor, batch, profile)


def _drift_line(name: str, pairs: list[tuple[dict, dict]]) -> float:
    """Prints the quiet runs' spread and the median ratio; returns that ratio."""
    quiet = [q["latency_ms"] for q, _ in pairs]
    loaded = [lo["latency_ms"] for _, lo in pairs]
    ratio = float(np.median(loaded) / np.median(quiet))
    print(f"{'':24} {len(pairs)} rounds in turn: quiet {', '.join(f'{q:.3f}' for q in quiet)} ms (max/min "
          f"{max(quiet) / min(quiet):.2f}); loaded {', '.join(f'{lo:.3f}' for lo in loaded)} ms; "
          f"median ratio {ratio:.2f}")
    return ratio
