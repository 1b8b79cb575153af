"""The `offline` job: MSE, size, latency, throughput and memory of one optimized artifact on one
hardware profile and one test set. Exclusive: a timing job has the host to itself.

deps: `artifact` (the optimize job) and `test` (a group of frames jobs, concatenated); with `timed: false`,
`timing` (the offline job that timed the same artifact on the same hardware, whose figures it takes).
"""
from __future__ import annotations

from typing import Any

from pydantic import Field

from matrix.kinds import register_kind
from pilotlab.specs.base import Spec


class OfflineSettings(Spec):
    batch: int = Field(64, ge=1, le=65_536, description="batch size of the throughput measurement")


class OfflineSpec(OfflineSettings):
    hardware: dict[str, Any] = Field(description='the profile {"name", "device", "threads"[, "worker_resource"]} '
                                                 '(pilotlab.hardware)')
    host: dict[str, Any] | None = Field(None, description="the host the planner expects; another is an error "
                                                          "(None: whichever host the profile's worker resource is on)")
    timing: dict[str, int | float] = Field({}, description="overrides of how long and how often to measure "
                                                     "(pilotlab.offline.TimingSettings), e.g. for quick tests")
    timed: bool = Field(True, description="False: the job measures MSE only and its timing figures are its `timing` "
                                          "dependency's (the same network on the same hardware, tested in another "
                                          "world): a network is timed once, whatever the worlds it is tested in")


def gpu_resources(params) -> dict[str, float]:
    return {"GPU": 1} if (params.get("hardware") or {}).get("device") == "cuda" else {}


def timing_resources(params) -> dict[str, float]:
    """Where a job that times on its profile's hardware may run on Dask: a GPU for a CUDA profile, and
    the machine a profile stands for (its worker resource)."""
    machine = (params.get("hardware") or {}).get("worker_resource")
    return gpu_resources(params) | ({machine: 1} if machine else {})


def timed(params) -> bool:
    return bool(params.get("timed", True))


register_kind("offline", "pilotlab.jobs.offline:run_offline", params=OfflineSpec, exclusive_for=timed,
              resources_for=lambda params: timing_resources(params) if timed(params) else gpu_resources(params))
