"""The `timing` job: how fast one optimized artifact runs on one hardware profile (batch-1 latency with
its samples, throughput, peak memory), measured once whatever test set or world it is evaluated in.
Exclusive: a timing job has the host to itself.

deps: `artifact` (the optimize job) and `frames` (a group of frames jobs: the training frames the
optimize job was made from, which only feed the network inputs; the test set is the offline jobs').
The offline jobs (MSE, size) and the laps (replayed latencies) of the artifact on that profile stand on it.
"""
from __future__ import annotations

from collections.abc import Callable
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


# What a job typically takes, for the scheduler and the time left of a store that has not run it
# (matrix.times): one for a CUDA profile, planned on a host without a GPU, says "not applicable" at once.
NOT_HERE_S, TIMING_S = 0.1, 2.0    # a timing: about 2 s, most of it the measuring itself


def not_applicable_here(params) -> bool:
    """A job for a CUDA profile whose planned host has no GPU (it is "not applicable" when it runs)."""
    host = params.get("host")
    return (params.get("hardware") or {}).get("device") == "cuda" and isinstance(host, dict) and not host.get("gpu")


def guess_here(seconds_for: Callable[[Any], float]) -> Callable[[Any], float]:
    """A kind's guess (`typical_for`) that knows a job that cannot run on its planned host ends at once."""
    return lambda params: NOT_HERE_S if not_applicable_here(params) else seconds_for(params)


register_kind("timing", "pilotlab.jobs.timing:run_timing", params=TimingSpec, exclusive=True,
              resources_for=timing_resources, typical_for=guess_here(lambda params: TIMING_S))
