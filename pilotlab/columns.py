"""The names of every metric a job result may carry, with units and meaning.

Job results, `results.csv` and the report tables all use these names, so they are defined once here.
A value that could not be measured is absent (or None), never 0. Sizes and memory in "MB" are MB of
2^20 bytes (MiB): the study's tables count so (its TF Lite baseline, 64.917... "MB", is bytes / 2^20),
and ours stay comparable with them.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Column:
    name: str
    unit: str
    doc: str
    better: str = ""  # "lower" | "higher" | "" (no preference)
    measured: bool = False  # a timing or memory figure: it differs from run to run, so compare by tolerance


OFFLINE = (
    Column("size_mb", "MB", "artifact size on disk (MB of 2^20 bytes, as the study's)", "lower"),
    Column("size_gz_mb", "MB", "artifact size gzip-compressed (what pruning's zeros and clustering's shared "
           "values save in storage and download; TF-MOT's measure)", "lower"),
    Column("params", "", "number of parameters (non-zero for pruned models: see nonzero_params)"),
    Column("nonzero_params", "", "parameters that are not zero"),
    Column("sparsity", "", "fraction of prunable weights that are exactly zero"),
    Column("mse", "", "MSE over v and w, on normalised labels (as the 2022 study reports)", "lower"),
    Column("mse_v", "", "MSE of v, normalised", "lower"),
    Column("mse_w", "", "MSE of w, normalised", "lower"),
    Column("mse_v_phys", "(m/s)^2", "MSE of v in physical units", "lower"),
    Column("mse_w_phys", "(rad/s)^2", "MSE of w in physical units", "lower"),
    Column("latency_ms", "ms", "batch-1 latency, median", "lower", measured=True),
    Column("latency_p10_ms", "ms", "batch-1 latency, 10th percentile", "lower", measured=True),
    Column("latency_p90_ms", "ms", "batch-1 latency, 90th percentile", "lower", measured=True),
    Column("latency_p99_ms", "ms", "batch-1 latency, 99th percentile", "lower", measured=True),
    Column("latency_runs", "", "timed batch-1 runs behind the latency figures", measured=True),
    Column("throughput_ips", "images/s", "throughput at the larger batch", "higher", measured=True),
    Column("throughput_p10_ips", "images/s", "throughput of the slower calls (10th percentile)", "higher",
           measured=True),
    Column("throughput_p90_ips", "images/s", "throughput of the faster calls (90th percentile)", "higher",
           measured=True),
    Column("throughput_batch", "", "batch size of the throughput measurement"),
    Column("peak_mem_mb", "MB", "peak resident memory added by loading and running the artifact", "lower",
           measured=True),
    Column("threads", "", "CPU threads used"),
    Column("timing_blocks", "", "blocks of timed batch-1 calls behind the latency (each at least 0.2 s)",
           measured=True),
    Column("timing_calls_discarded", "", "batch-1 calls a wait for a CPU overlapped: set aside and re-measured "
                                         "(kept in an unstable figure)", measured=True),
    Column("timing_cpu_per_wall", "", "this process's CPU time over wall time while timing the latency", measured=True),
    Column("timing_other_cores", "", "cores used by other processes (and steal) while timing the latency",
           measured=True),
    Column("timing_steal_cores", "", "cores taken by the hypervisor (steal) while timing the latency", measured=True),
    Column("test_frames", "", "frames in the test set"),
)

ONLINE = (
    Column("lap_completed", "", "the car completed the lap"),
    Column("completed_distance_m", "m", "distance driven along the centreline", "higher"),
    Column("percentage_completed", "%", "completed distance over circuit length", "higher"),
    Column("lap_seconds", "s", "simulated time of the lap (if completed)", "lower"),
    Column("average_speed", "m/s", "completed distance over simulated time", "higher"),
    Column("position_deviation_mae_m", "m", "mean distance from the red line", "lower"),
    Column("position_deviation_total_m", "m", "sum of distances from the red line over iterations", "lower"),
    Column("brain_frequency_sim_hz", "Hz", "brain iterations per simulated second", "higher"),
    Column("brain_frequency_real_hz", "Hz", "brain iterations per wall-clock second", "higher", measured=True),
    Column("mean_inference_ms", "ms", "mean time of one brain inference", "lower", measured=True),
    Column("real_time_factor", "", "simulated seconds per wall-clock second", "higher", measured=True),
    Column("suddenness", "", "mean change between consecutive commands", "lower"),
    Column("off_road_events", "", "times the car left the road", "lower"),
)

# BehaviorMetrics' own definitions (pilotlab.online.bm_metrics), against the expert's lap on the same
# circuit and direction: set beside the 2022 study's numbers. Ours above stay the primary ones.
BEHAVIORMETRICS = (
    Column("bm_lap_completed", "", "BehaviorMetrics: percentage completed above 100"),
    Column("bm_percentage_completed", "%", "BehaviorMetrics: expert-lap checkpoints reached within 5 m", "higher"),
    Column("bm_completed_distance_m", "m", "BehaviorMetrics: path length of the car's positions", "higher"),
    Column("bm_average_speed", "m/s", "BehaviorMetrics: path length over whole simulated seconds", "higher"),
    Column("bm_position_deviation_mae", "", "BehaviorMetrics: mean of 1000^d, d the metres from each "
           "expert-lap checkpoint to the run's spline (1 = perfect)", "lower"),
    Column("bm_position_deviation_total", "", "BehaviorMetrics: sum of 1000^d over the checkpoints", "lower"),
    Column("bm_brain_frequency_sim_hz", "Hz", "BehaviorMetrics: 1 / mean simulated iteration time", "higher"),
    Column("bm_brain_frequency_real_hz", "Hz", "BehaviorMetrics: 1 / mean brain iteration time", "higher",
           measured=True),
    Column("bm_mean_inference_ms", "ms", "BehaviorMetrics: mean inference time, first and last 10 dropped",
           "lower", measured=True),
    Column("bm_suddenness", "", "BehaviorMetrics: mean change between consecutive normalised outputs", "lower"),
)

# The latency tolerance search of a lap cell (pilotlab.online.tolerance).
TOLERANCE = (
    Column("latency_tolerance_ms", "ms", "largest injected latency (on the search's grid: step_ms up to max_ms, 10 "
           "and 1000 ms by default) at which the lap is still completed; none where the lap is lost with nothing "
           "injected, or was not searched (results.csv: latency_tolerance_searched)", "higher"),
)

BY_NAME = {c.name: c for c in OFFLINE + ONLINE + BEHAVIORMETRICS + TOLERANCE}
