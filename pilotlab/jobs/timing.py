"""The `timing` job's handler (params: pilotlab.specs.timing.TimingSpec): how fast one optimized
artifact runs on one hardware profile, fed frames of the training recordings (never the test set, so
editing the test set re-times nothing).

result: the pilotlab.columns names latency_ms, latency_p10_ms, latency_p90_ms, latency_p99_ms,
latency_runs, throughput_ips, throughput_p10_ips, throughput_p90_ips, throughput_batch, peak_mem_mb,
threads and the timing_* figures (pilotlab.offline); unstable ({metric: reason} for a timing that
stayed disturbed; absent when none did); cpu_time ({metric: reason} for a single-thread timing that is
the calls' thread CPU time, the wall clock being disturbed; absent when none is); latency_samples
("latency_ms.npy" in the artifacts: the batch-1 calls the latency is made of, float64 ms, in
measurement order: the clean calls, or every call's thread CPU time or wall time, which the laps
replay); plus strategy, hardware (the profile), host (the fingerprint of the host that timed it) and
hostname (its name, matrix.hostlock).
"""
from __future__ import annotations

import dataclasses

from matrix.hostlock import host_name
from matrix.kinds import JobContext
from pilotlab import offline
from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.hardware import check_available, check_host, check_on_its_machine, profile_from_dict
from pilotlab.specs.timing import TimingSpec


def timing_settings(job: str, spec: TimingSpec) -> offline.TimingSettings:
    known = {f.name for f in dataclasses.fields(offline.TimingSettings)} - {"throughput_batch"}
    if unknown := sorted(set(spec.timing) - known):
        raise PilotlabError(f"{job}: timing has no setting(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    return offline.TimingSettings(**{**spec.timing, "throughput_batch": spec.batch})


def run_timing(ctx: JobContext) -> dict:
    spec: TimingSpec = ctx.spec
    profile = profile_from_dict(spec.hardware)
    check_available(profile)
    check_on_its_machine(profile, ctx.name)
    host = check_host(ctx.name, spec.host)
    # the first recording's first frames are inputs enough (memory-mapped: the rest is never read)
    frames = FrameSet.load(ctx.dep_group("frames")[0].artifacts)
    settings = timing_settings(ctx.name, spec)
    artifact = ctx.dep("artifact")
    ctx.progress(0, 1, f"timing {artifact.result.get('strategy', '?')} on {profile.name}")
    result = offline.evaluate_timing(artifact.artifacts, profile, frames, settings, ctx.out)
    ctx.progress(1, 1)
    return {**result, "strategy": artifact.result.get("strategy"), "hardware": profile.as_dict(), "host": host,
            "hostname": host_name()}
