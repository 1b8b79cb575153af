"""The `offline` job: MSE, size, latency, throughput and memory of one optimized artifact on one
hardware profile and one test set. Exclusive: a timing job has the host to itself.

deps: `artifact` (the optimize job) and `test` (a group of frames jobs, concatenated).
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


def gpu_resources(params) -> dict[str, float]:
    return {"GPU": 1} if (params.get("hardware") or {}).get("device") == "cuda" else {}


def timing_resources(params) -> dict[str, float]:
    """Where a job that times on its profile's hardware may run on Dask: a GPU for a CUDA profile, and
    the machine a profile stands for (its worker resource)."""
    machine = (params.get("hardware") or {}).get("worker_resource")
    return gpu_resources(params) | ({machine: 1} if machine else {})


register_kind("offline", "pilotlab.jobs.offline:run_offline", params=OfflineSpec, exclusive=True,
              resources_for=timing_resources)
