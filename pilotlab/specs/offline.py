"""The `offline` job: MSE and size of one optimized artifact on one hardware profile and one test set,
beside the timing figures of its `timing` dependency. It measures no time, so it runs beside other jobs.

deps: `artifact` (the optimize job), `test` (a group of frames jobs, concatenated) and `timing` (the
timing job of the same artifact on the same hardware profile, whose figures it reports).
"""
from __future__ import annotations

from typing import Any

from pydantic import Field

from matrix.kinds import register_kind
from pilotlab.specs.base import Spec
from pilotlab.specs.timing import gpu_resources


class OfflineSpec(Spec):
    hardware: dict[str, Any] = Field(description='the profile {"name", "device", "threads"[, "worker_resource"]} '
                                                 '(pilotlab.hardware) the network runs on')
    host: dict[str, Any] | None = Field(None, description="the host its timing dependency is planned for (None: "
                                                          "whichever host the profile's worker resource is on); "
                                                          "not checked (the job times nothing), so that gc on "
                                                          "another host keeps it with its timing")


register_kind("offline", "pilotlab.jobs.offline:run_offline", params=OfflineSpec, resources_for=gpu_resources)
