"""Offline evaluation of one artifact on one hardware profile and one test FrameSet.

Metric names are those of `pilotlab.columns` (mse, mse_v, mse_w, mse_v_phys, mse_w_phys, size_mb,
latency_ms, latency_p90_ms, latency_p99_ms, latency_runs, throughput_ips, throughput_batch,
peak_mem_mb, threads, test_frames).

Timing: batch-1 latency times each `predict` call with perf_counter_ns after a warm-up, in blocks,
until the median is stable (or a time budget is spent); the per-call bookkeeping is two clock reads
and a list append, well under 1% of a PilotNet inference (the benchmark shows it against a bare
loop). Throughput is the median time of a larger batch.
"""
from __future__ import annotations

import resource
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.hardware import HardwareProfile
from pilotlab.predictor import Predictor, load_predictor, resolve_profile
from pilotlab.strategies.artifact import artifact_size_mb


@dataclass(frozen=True)
class TimingSettings:
    warmup_runs: int = 50
    warmup_seconds: float = 0.3
    min_runs: int = 300
    max_runs: int = 20_000
    max_seconds: float = 5.0          # budget for the batch-1 latency measurement
    block: int = 100                  # runs between stability checks
    stable_within: float = 0.01       # stop when the median moved less than 1% over a block
    throughput_batch: int = 64
    throughput_seconds: float = 1.5
    mse_batch: int = 64


LATENCY_SAMPLES = "latency_ms.npy"


def evaluate_offline(artifact_dir: Path, hardware: HardwareProfile | dict | str, test: FrameSet,
                     settings: TimingSettings = TimingSettings(), out: Path | None = None) -> dict:
    """Every offline metric of the artifact on `test` (see the module docstring).

    With `out`, the batch-1 latency samples (float64 ms, one per timed call, in measurement order)
    are saved there as `latency_ms.npy`, named by the result's `latency_samples`, so a closed-loop
    lap can replay the latency this job measured."""
    profile = resolve_profile(hardware)
    memory = PeakMemory()
    predictor = load_predictor(artifact_dir, profile)
    frames = max(1, predictor.meta.input_shape[1] // 3)
    result = {"size_mb": artifact_size_mb(artifact_dir), "threads": predictor.threads,
              "test_frames": len(test), **mse_metrics(predictor, test, frames, settings.mse_batch)}
    result.update(measure_throughput(predictor, sample_batch(test, settings.throughput_batch, frames), settings))
    result["peak_mem_mb"] = memory.peak_mb()
    latency = measure_latency(predictor.predict, sample_batch(test, 1, frames), settings)
    samples = latency.pop("samples_ms")
    result.update(latency)
    if out is not None:
        np.save(Path(out) / LATENCY_SAMPLES, samples)
        result["latency_samples"] = LATENCY_SAMPLES
    return result


def sample_batch(test: FrameSet, size: int, frames: int) -> np.ndarray:
    """`size` frames of the test set (repeated if it is smaller), C-contiguous float32."""
    index = np.arange(size) % len(test)
    return np.ascontiguousarray(test.inputs(index, frames).numpy())


def mse_metrics(predictor: Predictor, test: FrameSet, frames: int, batch_size: int) -> dict:
    ranges = LabelRanges.from_dict(predictor.meta.labels)
    predictions = np.concatenate([predictor.predict(np.ascontiguousarray(inputs.numpy()))
                                  for inputs, _ in test.batches(batch_size, frames=frames)])
    labels = np.asarray(test.labels, np.float32)
    normalised = (predictions - ranges.normalise(labels)) ** 2
    physical = (ranges.denormalise(predictions) - labels) ** 2
    return {"mse": float(normalised.mean()), "mse_v": float(normalised[:, 0].mean()),
            "mse_w": float(normalised[:, 1].mean()), "mse_v_phys": float(physical[:, 0].mean()),
            "mse_w_phys": float(physical[:, 1].mean())}


def warm_up(predict, batch: np.ndarray, runs: int, seconds: float) -> None:
    deadline = time.perf_counter() + seconds
    done = 0
    while done < runs or time.perf_counter() < deadline:
        predict(batch)
        done += 1


def measure_latency(predict, batch: np.ndarray, settings: TimingSettings = TimingSettings()) -> dict:
    """Batch-1 latency: median, p90, p99 (ms) of individually timed calls, and the calls' times
    (`samples_ms`, float64 ms in measurement order)."""
    warm_up(predict, batch, settings.warmup_runs, settings.warmup_seconds)
    clock = time.perf_counter_ns
    times: list[int] = []
    previous = None
    deadline = time.perf_counter() + settings.max_seconds
    while len(times) < settings.max_runs:
        for _ in range(settings.block):
            start = clock()
            predict(batch)
            times.append(clock() - start)
        median = float(np.median(times))
        stable = previous is not None and abs(median - previous) <= settings.stable_within * median
        if len(times) >= settings.min_runs and (stable or time.perf_counter() > deadline):
            break
        previous = median
    samples = np.asarray(times, np.float64) / 1e6
    p50, p90, p99 = np.percentile(samples, [50, 90, 99])
    return {"latency_ms": float(p50), "latency_p90_ms": float(p90), "latency_p99_ms": float(p99),
            "latency_runs": len(times), "samples_ms": samples}


def measure_throughput(predictor: Predictor, batch: np.ndarray, settings: TimingSettings = TimingSettings()) -> dict:
    """Images per second at a larger batch (median of timed calls)."""
    warm_up(predictor.predict, batch, 3, 0.1)
    times = []
    deadline = time.perf_counter() + settings.throughput_seconds
    while len(times) < 5 or time.perf_counter() < deadline:
        start = time.perf_counter()
        predictor.predict(batch)
        times.append(time.perf_counter() - start)
    return {"throughput_ips": len(batch) / float(np.median(times)), "throughput_batch": len(batch)}


class PeakMemory:
    """Peak resident memory since creation, over the resident memory at creation (MB).

    Linux lets a process reset its peak (writing 5 to /proc/self/clear_refs), so the figure covers
    loading and running the artifact only; elsewhere it falls back to the process's lifetime peak."""

    def __init__(self):
        self._resettable = _reset_peak()
        self._start = _status_kb("VmRSS") if self._resettable else 0

    def peak_mb(self) -> float:
        if self._resettable:
            return (_status_kb("VmHWM") - self._start) / 1024
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _reset_peak() -> bool:
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return _status_kb("VmHWM") > 0
    except OSError:
        return False


def _status_kb(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0
