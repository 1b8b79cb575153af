"""The optimize and offline job kinds, run through their registered handlers with a hand-made
JobContext, as the engine would."""
from __future__ import annotations

import json
import logging

import numpy as np
import pytest

import pilotlab.jobs.offline  # noqa: F401  (registers the kind)
import pilotlab.jobs.optimize  # noqa: F401
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


def dep(kind, folder, result=None, params=None) -> DepResult:
    return DepResult(key=f"{kind}-dep", kind=kind, params=params or {}, result=result or {}, artifacts=folder)


def optimize(tmp_path, trained, frames, strategy, options=None, hardware=None):
    params = {"strategy": strategy, "options": options or {}}
    if hardware:
        params["hardware"] = hardware
    ctx = context(tmp_path, "optimize", params, {"model": dep("train", trained),
                                                 "calibration": (dep("frames", frames),)})
    return ctx, KINDS.get("optimize").handler(ctx)


def test_optimize_then_offline(tmp_path, trained, frames, test_frames):
    ctx, result = optimize(tmp_path, trained, frames, "local_prune", {"finetune_epochs": 1, "batch_size": 16})
    assert result["strategy"] == "local_prune" and result["sparsity"] > 0.4
    assert result["options"]["conv"] == 0.3 and json.dumps(result)
    offline = context(tmp_path, "offline",
                      {"hardware": make_profile("cpu1").as_dict(), "host": host_fingerprint(), "batch": 8, "batch": 8, "timing": QUICK},
                      {"artifact": dep("optimize", ctx.out, result), "test": (dep("frames", test_frames),)})
    metrics = KINDS.get("offline").handler(offline)
    assert {"mse", "mse_v", "mse_w", "latency_ms", "throughput_ips", "size_mb", "peak_mem_mb"} <= set(metrics)
    assert set(metrics) - {"strategy", "hardware", "host", "hostname", "latency_samples", "unstable", "cpu_time"} \
        <= set(BY_NAME)
    assert metrics["host"] == host_fingerprint() and metrics["threads"] == 1 and json.dumps(metrics)
    assert metrics["hostname"] == host_name()
    samples = np.load(offline.out / metrics["latency_samples"])
    assert samples.dtype == np.float64 and samples.shape == (metrics["latency_runs"],)
    assert np.median(samples) == pytest.approx(metrics["latency_ms"])


def test_offline_refuses_to_time_for_another_host(tmp_path, trained, frames, test_frames):
    ctx, result = optimize(tmp_path, trained, frames, "baseline")
    other = {**host_fingerprint(), "cpu": "Some Other CPU"}
    offline = context(tmp_path, "offline", {"hardware": {"name": "cpu"}, "host": other, "batch": 8, "batch": 8, "timing": QUICK},
                      {"artifact": dep("optimize", ctx.out, result), "test": (dep("frames", test_frames),)})
    with pytest.raises(PilotlabError, match="Some Other CPU"):
        KINDS.get("offline").handler(offline)


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


def test_a_cuda_only_strategy_is_not_applicable_here(tmp_path, trained, frames):
    import torch
    if torch.cuda.is_available():
        pytest.skip("this host has a GPU")
    with pytest.raises(NotApplicable, match="CUDA"):
        optimize(tmp_path, trained, frames, "tensorrt", hardware={"name": "cuda"})


def test_kinds_are_registered_with_their_fingerprints():
    offline = KINDS.get("offline")
    assert offline.runs_alone({"hardware": {"name": "cpu"}}) and not offline.runs_alone({"timed": False})   # MSE only
    own = set(KINDS.get("optimize").code_for({"strategy": "qat"}))
    assert {"pilotlab.strategies.pt2e", "pilotlab.strategies.pt2e_graph", "pilotlab.training"} <= own
    assert not own & {"pilotlab.strategies.prune", "pilotlab.strategies.onnx_runtime"}   # other strategies'
    shared = set(KINDS.get("optimize").base_modules())
    assert {"pilotlab.strategies.registry", "pilotlab.hardware"} <= shared and "pilotlab.strategies.pt2e" not in shared
