"""The `offline` job's handler (params: pilotlab.specs.offline.OfflineSpec).

result: the pilotlab.columns names: mse, mse_v, mse_w, mse_v_phys, mse_w_phys, size_mb, size_gz_mb, latency_ms,
latency_p90_ms, latency_p99_ms, latency_runs, throughput_ips, throughput_batch, peak_mem_mb,
threads, test_frames, their percentiles and timing_* figures (pilotlab.offline); unstable
({metric: reason} for a timing that stayed disturbed; absent when none did); cpu_time ({metric:
reason} for a single-thread timing that is the calls' thread CPU time, the wall clock being disturbed;
absent when none is); latency_samples ("latency_ms.npy" in the artifacts: the batch-1 calls the latency
is made of, float64 ms, in measurement order: the clean calls, or every call's thread CPU time or wall
time); plus strategy, hardware (the
profile), host (the fingerprint of the host that timed it) and hostname (its name, matrix.hostlock).
Untimed (`timed: false`): the MSE and size figures of its own test set, every other figure its `timing`
dependency's, and timed_by (that job's name).
"""
from __future__ import annotations

import dataclasses

from matrix.hostlock import host_name
from matrix.kinds import JobContext
from pilotlab import offline
from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.hardware import check_available, check_host, profile_from_dict
from pilotlab.specs.offline import OfflineSpec


def timing_settings(job: str, spec: OfflineSpec) -> offline.TimingSettings:
    known = {f.name for f in dataclasses.fields(offline.TimingSettings)} - {"throughput_batch"}
    if unknown := sorted(set(spec.timing) - known):
        raise PilotlabError(f"{job}: timing has no setting(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    return offline.TimingSettings(**{**spec.timing, "throughput_batch": spec.batch})


def run_offline(ctx: JobContext) -> dict:
    spec: OfflineSpec = ctx.spec
    profile = profile_from_dict(spec.hardware)
    check_available(profile)
    host = check_host(ctx.name, spec.host)
    sets = [FrameSet.load(dep.artifacts) for dep in ctx.dep_group("test")]
    test = sets[0] if len(sets) == 1 else FrameSet.concat(sets)
    settings = timing_settings(ctx.name, spec)
    if not spec.timed:
        return accuracy_beside_timing(ctx, test, settings)
    ctx.progress(0, 1, f"timing {ctx.dep('artifact').result.get('strategy', '?')} on {profile.name}")
    result = offline.evaluate_offline(ctx.dep("artifact").artifacts, profile, test, settings, ctx.out)
    ctx.progress(1, 1)
    return {**result, "strategy": ctx.dep("artifact").result.get("strategy"),
            "hardware": profile.as_dict(), "host": host, "hostname": host_name()}


def accuracy_beside_timing(ctx: JobContext, test: FrameSet, settings: offline.TimingSettings) -> dict:
    """MSE on this job's test set; every timing figure is the `timing` job's (the same network and
    hardware), with the name of the job that measured it."""
    timing = ctx.dep("timing")
    measured = {key: value for key, value in timing.result.items() if key != "latency_samples"}
    accuracy = offline.evaluate_accuracy(ctx.dep("artifact").artifacts, ctx.spec.hardware, test, settings)
    return {**measured, **accuracy, "timed_by": timing.name}
