"""The optimize, timing and offline job kinds, run through their registered handlers with a hand-made
JobContext, as the engine would."""
from __future__ import annotations

import json
import logging
import os

import numpy as np
import pytest

import pilotlab.jobs.offline  # noqa: F401  (registers the kind)
import pilotlab.jobs.optimize  # noqa: F401
import pilotlab.jobs.timing  # noqa: F401
from matrix.hostlock import host_name
from matrix.kinds import KINDS, DepResult, JobContext, NotApplicable
from pilotlab.columns import BY_NAME
from pilotlab.errors import PilotlabError
from pilotlab.hardware import host_fingerprint, make_profile

QUICK = {"warmup_runs": 5, "warmup_seconds": 0.0, "min_runs": 30, "max_seconds": 0.5, "block_seconds": 0.05,
         "min_blocks": 2, "throughput_seconds": 0.1, "throughput_min_runs": 3}


def context(tmp_path, kind, params, deps) -> JobContext:
    out = tmp_path / kind / "artifacts"
    out.mkdir(parents=True)
    return JobContext(key=f"{kind}-key", kind=kind, name=f"{kind}:test", params=params, deps=deps,
                      out=out, cache=tmp_path / "cache", log=logging.getLogger("test"))


def dep(kind, folder, result=None, params=None, name="") -> DepResult:
    return DepResult(key=f"{kind}-dep", kind=kind, params=params or {}, result=result or {}, artifacts=folder,
                     name=name)


def optimize(tmp_path, trained, frames, strategy, options=None, hardware=None):
    params = {"strategy": strategy, "options": options or {}}
    if hardware:
        params["hardware"] = hardware
    ctx = context(tmp_path, "optimize", params, {"model": dep("train", trained),
                                                 "calibration": (dep("frames", frames),)})
    return ctx, KINDS.get("optimize").handler(ctx)


def test_optimize_then_timing_then_offline(tmp_path, trained, frames, test_frames):
    ctx, result = optimize(tmp_path, trained, frames, "local_prune", {"finetune_epochs": 1, "batch_size": 16})
    assert result["strategy"] == "local_prune" and result["sparsity"] > 0.4
    assert result["options"]["conv"] == 0.3 and json.dumps(result)
    artifact = dep("optimize", ctx.out, result)
    timing = context(tmp_path, "timing", {"hardware": make_profile("cpu1").as_dict(), "host": host_fingerprint(),
                                          "batch": 8, "timing": QUICK},
                     {"artifact": artifact, "frames": (dep("frames", frames),)})
    timed = KINDS.get("timing").handler(timing)
    assert {"latency_ms", "throughput_ips", "peak_mem_mb", "threads"} <= set(timed) and "mse" not in timed
    assert not {"size_mb", "test_frames"} & set(timed)
    assert set(timed) - {"strategy", "hardware", "host", "hostname", "latency_samples", "unstable", "cpu_time"} \
        <= set(BY_NAME)
    assert timed["host"] == host_fingerprint() and timed["threads"] == 1 and timed["throughput_batch"] == 8
    assert timed["hostname"] == host_name() and timed["strategy"] == "local_prune" and json.dumps(timed)
    samples = np.load(timing.out / timed["latency_samples"])
    assert samples.dtype == np.float64 and samples.shape == (timed["latency_runs"],)
    assert np.median(samples) == pytest.approx(timed["latency_ms"])

    offline = context(tmp_path, "offline", {"hardware": make_profile("cpu1").as_dict(), "host": host_fingerprint()},
                      {"artifact": artifact, "test": (dep("frames", test_frames),),
                       "timing": dep("timing", timing.out, timed, name="timing pilotnet/local_prune on cpu1")})
    metrics = KINDS.get("offline").handler(offline)
    assert {"mse", "mse_v", "mse_w", "size_mb", "test_frames"} <= set(metrics) and json.dumps(metrics)
    assert {key: metrics[key] for key in timed if key != "latency_samples"} == \
        {key: value for key, value in timed.items() if key != "latency_samples"}   # the timing's figures
    assert "latency_samples" not in metrics and metrics["timed_by"] == "timing pilotnet/local_prune on cpu1"
    assert not any(offline.out.iterdir())   # the samples the laps replay stay the timing job's


def test_timing_refuses_to_time_for_another_host(tmp_path, trained, frames):
    ctx, result = optimize(tmp_path, trained, frames, "baseline")
    other = {**host_fingerprint(), "cpu": "Some Other CPU"}
    timing = context(tmp_path, "timing", {"hardware": {"name": "cpu"}, "host": other, "batch": 8, "timing": QUICK},
                     {"artifact": dep("optimize", ctx.out, result), "frames": (dep("frames", frames),)})
    with pytest.raises(PilotlabError, match="Some Other CPU"):
        KINDS.get("timing").handler(timing)


def test_timing_overrides_are_checked(tmp_path, trained, frames):
    ctx, result = optimize(tmp_path, trained, frames, "baseline")
    timing = context(tmp_path, "timing", {"hardware": {"name": "cpu"}, "timing": {"max_second": 1}},
                     {"artifact": dep("optimize", ctx.out, result), "frames": (dep("frames", frames),)})
    with pytest.raises(PilotlabError, match="timing has no setting.s. max_second; known: .*max_seconds"):
        KINDS.get("timing").handler(timing)


def test_an_optimize_job_runs_at_the_workers_thread_count_whatever_ran_before(tmp_path, trained, frames):
    """A timing job or the training leaves torch at its own thread count in the worker; the fine-tune
    after it must not inherit it (its figures would then depend on what the worker ran before)."""
    import torch
    from pilotlab.jobs.optimize import WORKER_THREADS
    seen = []
    torch.set_num_threads(WORKER_THREADS + 1)
    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr("pilotlab.jobs.optimize.apply_strategy",
                          lambda *args: seen.append(torch.get_num_threads()) or {"strategy": "baseline"})
            optimize(tmp_path, trained, frames, "baseline")
    finally:
        torch.set_num_threads(WORKER_THREADS)
    assert seen == [WORKER_THREADS]


def test_the_worker_s_thread_count_is_its_share_even_when_a_training_ran_first_in_it():
    """The handler's module is imported by the worker's first optimize job: after a training in the same
    worker (every core) its share was read as 2 threads, and the quickstart's fine-tune gave another
    network (off the road after 6 s) than when it ran in a fresh worker (a whole lap)."""
    import subprocess
    import sys
    from tests.child import ROOT, python_path
    code = ("import torch; torch.set_num_threads(2)\n"          # what the training leaves in the worker
            "from pilotlab.jobs.optimize import WORKER_THREADS; print(WORKER_THREADS)")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": python_path(ROOT)}   # a worker's share on 2 cores
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1"]


def test_a_cuda_only_strategy_is_not_applicable_here(tmp_path, trained, frames):
    import torch
    if torch.cuda.is_available():
        pytest.skip("this host has a GPU")
    with pytest.raises(NotApplicable, match="CUDA"):
        optimize(tmp_path, trained, frames, "tensorrt", hardware={"name": "cuda"})


def test_kinds_are_registered_with_their_fingerprints():
    timing, offline = KINDS.get("timing"), KINDS.get("offline")
    cpu, jetson = {"hardware": {"name": "cpu"}}, {"hardware": {"name": "jetson", "worker_resource": "JETSON"}}
    assert timing.runs_alone(cpu) and timing.runs_alone(jetson)             # it times: the host to itself
    assert not offline.runs_alone(cpu) and not offline.runs_alone(jetson)   # MSE only, beside other jobs
    assert timing.resources_for(jetson) == {"JETSON": 1} and offline.resources_for(jetson) == {}
    gpu = {"hardware": {"name": "cuda", "device": "cuda"}}
    assert timing.resources_for(gpu) == offline.resources_for(gpu) == {"GPU": 1}
    own = set(KINDS.get("optimize").code_for({"strategy": "qat"}))
    assert {"pilotlab.strategies.pt2e", "pilotlab.strategies.pt2e_graph", "pilotlab.training"} <= own
    assert not own & {"pilotlab.strategies.prune", "pilotlab.strategies.onnx_runtime"}   # other strategies'
    shared = set(KINDS.get("optimize").base_modules())
    assert {"pilotlab.strategies.registry", "pilotlab.hardware"} <= shared and "pilotlab.strategies.pt2e" not in shared
