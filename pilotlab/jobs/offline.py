"""The `offline` job kind: MSE, size, latency, throughput and memory of one optimized artifact on
one hardware profile and one test set. Registered exclusive: timing jobs run alone.

params:
    hardware   dict  the profile {"name", "device", "threads"} (pilotlab.hardware)
    host       dict  pilotlab.hardware.host_fingerprint() of the machine the planner expects; a
                     different host is an error, so timings are never filed under another machine
    timing     dict  (optional) overrides of pilotlab.offline.TimingSettings (throughput_batch, ...)
deps:
    artifact   the optimize job (its artifacts are the artifact folder)
    test       group of frames jobs (FrameSet folders), concatenated
result:
    the pilotlab.columns names: mse, mse_v, mse_w, mse_v_phys, mse_w_phys, size_mb, latency_ms,
    latency_p90_ms, latency_p99_ms, latency_runs, throughput_ips, throughput_batch, peak_mem_mb,
    threads, test_frames; plus strategy, hardware (the profile) and host (the fingerprint).
"""
from __future__ import annotations

import dataclasses

from matrix.kinds import JobContext, job_kind
from pilotlab import offline, predictor
from pilotlab.data.frames import FrameSet
from pilotlab.errors import PilotlabError
from pilotlab.hardware import check_available, describe_host, host_fingerprint, profile_from_dict


@job_kind("offline", code=[offline, predictor], exclusive=True)
def run_offline(ctx: JobContext) -> dict:
    profile = profile_from_dict(ctx.params["hardware"])
    check_available(profile)
    host = host_fingerprint()
    expected = ctx.params.get("host")
    if expected is not None and expected != host:
        raise PilotlabError(f"{ctx.name}: planned for host {describe_host(expected)} but running on "
                            f"{describe_host(host)}; plan the run on the machine that times it")
    sets = [FrameSet.load(dep.artifacts) for dep in ctx.dep_group("test")]
    test = sets[0] if len(sets) == 1 else FrameSet.concat(sets)
    settings = _settings(ctx.params.get("timing") or {})
    ctx.progress(0, 1, f"timing {ctx.dep('artifact').result.get('strategy', '?')} on {profile.name}")
    result = offline.evaluate_offline(ctx.dep("artifact").artifacts, profile, test, settings)
    ctx.progress(1, 1)
    return {**result, "strategy": ctx.dep("artifact").result.get("strategy"),
            "hardware": profile.as_dict(), "host": host}


def _settings(overrides: dict) -> offline.TimingSettings:
    known = {f.name for f in dataclasses.fields(offline.TimingSettings)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise PilotlabError(f"offline timing: unknown option(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    return offline.TimingSettings(**overrides)
