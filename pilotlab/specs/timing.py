"""The `timing` job: how fast one optimized artifact runs on one hardware profile (batch-1 latency with
its samples, throughput, peak memory), measured once whatever test set or world it is evaluated in.
Exclusive: a timing job has the host to itself (but for one that will not time: a CUDA profile's on a
host without a GPU).

deps: `artifact` (the optimize job) and `frames` (a group of frames jobs: the training frames the
optimize job was made from, which only feed the network inputs; the test set is the offline jobs').
The offline jobs (MSE, size) and the laps (replayed latencies) of the artifact on that profile stand on it.
"""
from __future__ import annotations

from typing import Any

from pydantic import Field

from matrix.kinds import register_kind
from pilotlab.specs.base import Spec


class OfflineSettings(Spec):
    """The recipe's `offline:` settings of the timing jobs (beside `data`, the offline jobs' test set)."""
    batch: int = Field(64, ge=1, le=65_536, description="batch size of the throughput measurement")


class TimingSpec(OfflineSettings):
    hardware: dict[str, Any] = Field(description='the profile {"name", "device", "threads"[, "worker_resource"]} '
                                                 '(pilotlab.hardware)')
    host: dict[str, Any] | None = Field(None, description="the host the planner expects; another is an error "
                                                          "(None: whichever host the profile's worker resource is on)")
    timing: dict[str, int | float] = Field({}, description="overrides of how long and how often to measure "
                                                           "(pilotlab.offline.TimingSettings), e.g. for quick tests")


def gpu_resources(params) -> dict[str, float]:
    return {"GPU": 1} if (params.get("hardware") or {}).get("device") == "cuda" else {}


def timing_resources(params) -> dict[str, float]:
    """Where a job that times on its profile's hardware may run on Dask: a GPU for a CUDA profile, and
    the machine a profile stands for (its worker resource)."""
    machine = (params.get("hardware") or {}).get("worker_resource")
    return gpu_resources(params) | ({machine: 1} if machine else {})


def planned_without_gpu(params) -> bool:
    """A job for a CUDA profile whose planned host has no GPU: it says "not applicable" as it starts."""
    host = params.get("host")
    return (params.get("hardware") or {}).get("device") == "cuda" and isinstance(host, dict) and not host.get("gpu")


def times_its_host(params) -> bool:
    """Whether the job measures time on its host, so runs alone there: not one that will not time at all
    (the study's 24 CUDA timings on a host without a GPU each held both cores for a tenth of a second)."""
    return not planned_without_gpu(params)


register_kind("timing", "pilotlab.jobs.timing:run_timing", params=TimingSpec, exclusive_for=times_its_host,
              resources_for=timing_resources)
