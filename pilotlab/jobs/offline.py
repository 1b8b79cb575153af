"""The `offline` job's handler (params: pilotlab.specs.offline.OfflineSpec): MSE and size of one
optimized artifact on one test set, beside the figures of the `timing` job that timed it on the same
hardware profile (the job itself times nothing).

result: the pilotlab.columns names mse, mse_v, mse_w, mse_v_phys, mse_w_phys, size_mb, size_gz_mb,
threads and test_frames, measured here on its own test set; every figure of its `timing` dependency's
result (pilotlab.jobs.timing: latency_ms and its percentiles, latency_runs, throughput_ips and its
percentiles, throughput_batch, peak_mem_mb, the timing_* figures, unstable, cpu_time, strategy,
hardware, host and hostname) but its latency_samples (they stay in that job's artifacts, which the
laps replay); and timed_by (that job's name).
"""
from __future__ import annotations

from matrix.kinds import JobContext
from pilotlab import offline
from pilotlab.data.frames import FrameSet
from pilotlab.hardware import check_available, profile_from_dict
from pilotlab.specs.offline import OfflineSpec


def run_offline(ctx: JobContext) -> dict:
    spec: OfflineSpec = ctx.spec
    profile = profile_from_dict(spec.hardware)
    check_available(profile)
    sets = [FrameSet.load(dep.artifacts) for dep in ctx.dep_group("test")]
    test = sets[0] if len(sets) == 1 else FrameSet.concat(sets)
    return accuracy_beside_timing(ctx, test)


def accuracy_beside_timing(ctx: JobContext, test: FrameSet) -> dict:
    """MSE on this job's test set; every timing figure is the `timing` job's (the same network and
    hardware), with the name of the job that measured it."""
    timing = ctx.dep("timing")
    measured = {key: value for key, value in timing.result.items() if key != "latency_samples"}
    accuracy = offline.evaluate_accuracy(ctx.dep("artifact").artifacts, ctx.spec.hardware, test)
    return {**measured, **accuracy, "timed_by": timing.name}
