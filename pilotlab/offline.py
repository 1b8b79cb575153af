"""Offline evaluation of one artifact on one hardware profile: its MSE and size on a test FrameSet
(evaluate_accuracy, the `offline` job) and its timings (evaluate_timing, the `timing` job).

Metric names are those of `pilotlab.columns` (mse, mse_v, mse_w, mse_v_phys, mse_w_phys, size_mb, size_gz_mb,
latency_ms and its percentiles, latency_runs, throughput_ips and its percentiles, throughput_batch,
peak_mem_mb, threads, test_frames, and the timing_* figures that say how the timings were taken).

Timing (pilotlab.timing): after a warm-up, batch-1 latency times each `predict` call with
perf_counter_ns and reads how long this process's threads waited for a CPU meanwhile (their
run-queue wait); calls that waited are set aside and re-measured within a bounded budget, and the
latency is the median of the clean calls, with p10/p90/p99. Throughput is the batch over the median
time of a larger batch's clean calls. A figure that could not be had from enough clean calls is the
median of all calls and is listed in the result's `unstable` ({metric: reason}). The per-call
bookkeeping (two clock reads, one pread per thread, two list appends) happens outside the timed
span; the benchmark compares the figure with a bare loop.
"""
from __future__ import annotations

import resource
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pilotlab import timing
from pilotlab.data.frames import FrameSet, LabelRanges
from pilotlab.errors import PilotlabError
from pilotlab.hardware import HardwareProfile, within_share
from pilotlab.predictor import Predictor, load_predictor, resolve_profile
from pilotlab.strategies.artifact import artifact_size_gz_mb, artifact_size_mb


@dataclass(frozen=True)
class TimingSettings:
    warmup_runs: int = 50
    warmup_seconds: float = 0.3
    min_runs: int = 300
    max_runs: int = 20_000
    max_seconds: float = 5.0          # budget for the batch-1 latency when nothing disturbs it
    # 0.1 s: the 5 blocks a figure takes at least are then half a second. Four timings each of five study
    # artifacts, quiet, interleaved with the 0.2 s blocks and 1 s of throughput (2026-11-28): the
    # medians spread over the four as much (latency 1.6-15 % against 1.5-12 %, throughput 1.5-7.5 %
    # against 1.9-10 %: the spread is between runs, not within one), and a timing job took 1.6 s instead
    # of 2.7. Each is exclusive: 24 of them were 65 s of the study's wall time.
    block_seconds: float = 0.1        # timed calls between two looks at the CPU's load
    min_blocks: int = 5               # clean blocks behind a figure, at least
    attempts: int = 3                 # disturbed blocks are re-measured within attempts × the budget
    stable_within: float = 0.01       # stop when the median moved less than 1% over a block
    max_wait_share: float = 0.02      # a clean call's threads waited for a CPU at most 2 % of its time
    min_clean_share: float = 0.25     # a stable figure: at least a quarter of the calls clean
    throughput_batch: int = 64
    # the 5 blocks the plan takes at least (see block_seconds; 1.5 s spread as 1 s did, earlier)
    throughput_seconds: float = 0.5
    throughput_min_runs: int = 10
    mse_batch: int = 64

    def plan(self) -> timing.Plan:
        return timing.Plan(self.min_runs, self.max_runs, self.min_blocks, self.block_seconds, self.max_seconds,
                           self.attempts, self.stable_within)

    def throughput_plan(self) -> timing.Plan:
        return timing.Plan(self.throughput_min_runs, self.max_runs, self.min_blocks, self.block_seconds,
                           self.throughput_seconds, self.attempts, stable_within=0.0)

    def limits(self, device: str = "cpu") -> timing.Limits:
        # a GPU timing waits for the device off the CPU: its CPU time says nothing about interference
        return timing.Limits(max_wait_share=self.max_wait_share, min_clean_share=self.min_clean_share,
                             min_cpu_per_wall=0.9 if device == "cpu" else 0.0)


LATENCY_SAMPLES = "latency_ms.npy"


def evaluate_offline(artifact_dir: Path, hardware: HardwareProfile | dict | str, test: FrameSet,
                     settings: TimingSettings = TimingSettings(), out: Path | None = None) -> dict:
    """Every offline metric of the artifact on `test` (see the module docstring): its size and MSE
    (evaluate_accuracy), then its timings (evaluate_timing, fed frames of `test`)."""
    accuracy = evaluate_accuracy(artifact_dir, hardware, test, settings)
    return {**evaluate_timing(artifact_dir, hardware, test, settings, out), **accuracy}


def evaluate_timing(artifact_dir: Path, hardware: HardwareProfile | dict | str, frames: FrameSet,
                    settings: TimingSettings = TimingSettings(), out: Path | None = None) -> dict:
    """The artifact's timings on `hardware` (see the module docstring): batch-1 latency, throughput at
    `settings.throughput_batch`, peak memory and threads, fed the first frames of `frames` (what a
    network sees does not change how long it takes, so any recording of its inputs will do).

    With `out`, the batch-1 latency samples (float64 ms, one per timed call the latency is made of:
    the clean calls, or every call when unstable; in measurement order) are saved there as
    `latency_ms.npy`, named by the result's `latency_samples`, so a closed-loop lap can replay the
    latency this job measured."""
    memory = PeakMemory()
    predictor = load_predictor(artifact_dir, resolve_profile(hardware))
    stacked = max(1, predictor.meta.input_shape[1] // 3)
    throughput = measure_throughput(predictor, sample_batch(frames, settings.throughput_batch, stacked), settings)
    result = {"threads": predictor.threads, "peak_mem_mb": memory.peak_mb()}
    latency = measure_latency(predictor.predict, sample_batch(frames, 1, stacked), settings, predictor.hardware)
    samples = latency.pop("samples_ms")
    unstable = {**latency.pop("unstable"), **throughput.pop("unstable")}
    cpu_time = {**latency.pop("cpu_time"), **throughput.pop("cpu_time")}
    result.update(latency)
    result.update(throughput)
    if unstable:
        result["unstable"] = unstable
    if cpu_time:
        result["cpu_time"] = cpu_time
    if out is not None:
        np.save(Path(out) / LATENCY_SAMPLES, samples)
        result["latency_samples"] = LATENCY_SAMPLES
    return result


def evaluate_accuracy(artifact_dir: Path, hardware: HardwareProfile | dict | str, test: FrameSet,
                      settings: TimingSettings = TimingSettings()) -> dict:
    """The offline metrics that do not time: size, threads (the profile's), MSE on `test`.

    The MSE is computed on this worker's share of the cores (hardware.within_share), not the profile's
    thread count: nothing here is timed, and an offline job runs beside other jobs (the study's
    2-thread MSE passes beside each other took 9-10 s instead of 2-3 s)."""
    test.check_finite("test data")
    profile = resolve_profile(hardware)
    predictor = load_predictor(artifact_dir, within_share(profile), spin=False)
    frames = max(1, predictor.meta.input_shape[1] // 3)
    return {"size_mb": artifact_size_mb(artifact_dir), "size_gz_mb": artifact_size_gz_mb(artifact_dir),
            "threads": profile.cpu_threads, "test_frames": len(test),
            **mse_metrics(predictor, test, frames, settings.mse_batch)}


def sample_batch(recording: FrameSet, size: int, frames: int) -> np.ndarray:
    """`size` inputs from the recording's first frames (repeated if it is shorter), C-contiguous float32."""
    index = np.arange(size) % len(recording)
    return np.ascontiguousarray(recording.inputs(index, frames).numpy())


def mse_metrics(predictor: Predictor, test: FrameSet, frames: int, batch_size: int) -> dict:
    ranges = LabelRanges.from_dict(predictor.meta.labels)
    predictions = np.concatenate([predictor.predict(np.ascontiguousarray(inputs.numpy()))
                                  for inputs, _ in test.batches(batch_size, frames=frames)])
    labels = np.asarray(test.labels, np.float32)
    bad = np.flatnonzero(~np.isfinite(predictions).all(axis=1))
    if len(bad):
        raise PilotlabError(f"the model predicts NaN or infinity for {len(bad)} of {len(test)} test frames (first: "
                            f"frame {int(bad[0])}), so its MSE is not a number: the optimized model is broken "
                            "(an overflow in reduced precision?); check its strategy's options")
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


def measure_latency(predict, batch: np.ndarray, settings: TimingSettings = TimingSettings(),
                    hardware: HardwareProfile | None = None) -> dict:
    """Batch-1 latency (ms): median, p10, p90, p99 of individually timed calls of the clean blocks;
    how they were taken (timing_*); `samples_ms`, those calls' times (float64 ms, in measurement
    order); `unstable`, {"latency_ms": reason} when too few blocks were clean; `cpu_time`,
    {"latency_ms": reason} when the figure is the calls' thread CPU time instead (pilotlab.timing)."""
    hardware = hardware or HardwareProfile("cpu")
    warm_up(predict, batch, settings.warmup_runs, settings.warmup_seconds)
    measured = timing.measure(lambda: predict(batch), _needed_cores(hardware), settings.plan(),
                              settings.limits(hardware.device), cpu_clock=_single_thread(hardware))
    samples = measured.samples_ns().astype(np.float64) / 1e6
    p10, p50, p90, p99 = np.percentile(samples, [10, 50, 90, 99])
    load = measured.summary()
    result = {"latency_ms": float(p50), "latency_p10_ms": float(p10), "latency_p90_ms": float(p90),
              "latency_p99_ms": float(p99), "latency_runs": len(samples), "timing_blocks": load["blocks"],
              "timing_calls_discarded": load["discarded"], "timing_cpu_per_wall": load["cpu_per_wall"],
              "timing_other_cores": load["others_cores"], "timing_steal_cores": load["steal_cores"],
              "samples_ms": samples, **clock_notes(measured, "latency_ms")}
    return {k: v for k, v in result.items() if v is not None}


def measure_throughput(predictor: Predictor, batch: np.ndarray, settings: TimingSettings = TimingSettings()) -> dict:
    """Images per second at a larger batch: the batch over the median call time of the clean blocks,
    with the 10th and 90th percentiles; `unstable` as for the latency."""
    warm_up(predictor.predict, batch, 3, 0.1)
    measured = timing.measure(lambda: predictor.predict(batch), _needed_cores(predictor.hardware),
                              settings.throughput_plan(), settings.limits(predictor.hardware.device),
                              cpu_clock=_single_thread(predictor.hardware))
    slow, median, fast = np.percentile(measured.samples_ns() / 1e9, [90, 50, 10])
    return {"throughput_ips": len(batch) / median, "throughput_p10_ips": len(batch) / slow,
            "throughput_p90_ips": len(batch) / fast, "throughput_batch": len(batch),
            **clock_notes(measured, "throughput_ips")}


def clock_notes(measured: timing.Measurement, metric: str) -> dict[str, dict[str, str]]:
    """{"unstable": {metric: reason}} where the figure stayed disturbed, {"cpu_time": {metric: reason}}
    where it is the calls' thread CPU time instead (each {} otherwise)."""
    if measured.stable:
        return {"unstable": {}, "cpu_time": {}}
    if cpu := measured.cpu_time_reason():
        return {"unstable": {}, "cpu_time": {metric: cpu}}
    return {"unstable": {metric: measured.reason()}, "cpu_time": {}}


def _single_thread(hardware: HardwareProfile) -> bool:
    """A timing whose work runs on the calling thread: its CPU time can stand for it on a busy machine."""
    return hardware.device == "cpu" and hardware.cpu_threads == 1


def _needed_cores(hardware: HardwareProfile) -> int:
    """Cores the timing needs to itself: the profile's threads on a CPU, the feeding thread on a GPU."""
    return hardware.cpu_threads if hardware.device == "cpu" else 1


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
