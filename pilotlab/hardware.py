"""Hardware profiles (where an artifact is run and timed) and the host fingerprint.

A profile is pure data, so it can travel in job params:

    {"name": "cpu1", "device": "cpu", "threads": 1}

Built in: `cpu` (all cores), `cpu1` (one thread), `cuda` (the first GPU). A recipe may define more
(a built-in's name only with its own settings) under `hardware:` with the options of `HardwareOptions`
(their one home: the recipe, the job params and the profiles are made from it): `device` ("cpu" |
"cuda"), `threads` (CPU threads; omitted = all cores)
and `worker_resource`, the Dask worker resource of the machine the profile stands for (its timing jobs
run only on workers started with `--resources NAME=1`, and are keyed by the profile, not by the planning
host's fingerprint; their results record the host that ran them).
A profile that cannot run on this host raises `matrix.NotApplicable` with the reason, so the report
shows "not applicable: …" instead of a crash.

The host fingerprint (CPU model, core count, GPU name) goes into the key of every timing job, so
timings measured on another machine are never shown as this one's.
"""
from __future__ import annotations

import contextlib
import glob
import os
import platform
import re
from dataclasses import asdict, dataclass, replace
from functools import cache
from pathlib import Path
from typing import Any, Literal

import pydantic
from pydantic import Field

from matrix.kinds import NotApplicable
from matrix.runs import cores, worker_share
from pilotlab.cpuinfo import cpu_model
from pilotlab.errors import PilotlabError
from pilotlab.specs.base import Spec

class HardwareOptions(Spec):
    """What a hardware profile is made of, wherever it is given (recipe, job params)."""
    device: Literal["cpu", "cuda"] = "cpu"
    threads: int | None = Field(None, ge=1, description="CPU threads for torch and ONNX Runtime; omitted: every core")
    worker_resource: str | None = Field(None, description="the Dask worker resource of the machine this profile "
                                        "stands for: its timing jobs run only on workers started with --resources NAME=1")

    @pydantic.field_validator("worker_resource")
    @classmethod
    def _resource_name(cls, name: str | None) -> str | None:
        if name is not None and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.-]*", name):
            raise ValueError(f"{name!r} is not a Dask resource name: give the NAME of the workers' "
                             "`--resources NAME=1` (letters, digits, _ . -)")
        return name


@dataclass(frozen=True)
class HardwareProfile:
    name: str
    device: str = "cpu"
    threads: int | None = None      # CPU threads for torch and ONNX Runtime; None = every core
    worker_resource: str | None = None   # the Dask worker resource of the machine it stands for

    def as_dict(self) -> dict[str, Any]:
        """As job params carry it (no worker_resource where there is none: keys from before stay valid)."""
        data = asdict(self)
        if self.worker_resource is None:
            del data["worker_resource"]
        return data

    @property
    def host(self) -> dict[str, Any] | None:
        """The host fingerprint its timing jobs are planned for: this host's, or None for a profile that
        stands for a Dask worker's machine (that one's is recorded when it runs)."""
        return None if self.worker_resource else host_fingerprint()

    @property
    def cpu_threads(self) -> int:
        return self.threads or cpu_count()


BUILTIN = {
    "cpu": HardwareProfile("cpu", "cpu", None),
    "cpu1": HardwareProfile("cpu1", "cpu", 1),
    "cuda": HardwareProfile("cuda", "cuda", None),
}


def cpu_count() -> int:
    """Cores this process may run on (the affinity mask, not the machine's total)."""
    return cores()


def within_share(profile: HardwareProfile) -> HardwareProfile:
    """`profile` with at most this process's share of the cores: for work whose speed is not measured
    (a replayed lap), which must not take the cores of the job beside it."""
    if profile.device != "cpu":
        return profile
    return replace(profile, threads=min(profile.cpu_threads, worker_share()))


def make_profile(name: str, options: dict[str, Any] | None = None) -> HardwareProfile:
    """The built-in profile `name`, or a recipe-defined one from `options` (HardwareOptions)."""
    if not options:
        if name not in BUILTIN:
            from matrix.errors import UnknownNameError
            raise UnknownNameError("hardware profile", name, BUILTIN)
        return BUILTIN[name]
    unknown = sorted(set(options) - set(HardwareOptions.model_fields))
    if unknown:
        raise PilotlabError(f"hardware.{name}: unknown option(s) {', '.join(map(str, unknown))}; a hardware profile "
                            "has: device (cpu | cuda), threads (an integer ≥ 1), worker_resource (a Dask resource name)")
    try:
        valid = HardwareOptions.model_validate(options)
    except pydantic.ValidationError as error:
        first = error.errors(include_url=False)[0]
        field, message = ".".join(map(str, first["loc"])), first["msg"].removeprefix("Value error, ")
        raise PilotlabError(f"hardware.{name}.{field}: {message} (got {first.get('input')!r:.60})") from None
    return HardwareProfile(name, **valid.model_dump())


def recipe_profile(name: str, options: dict[str, Any] | None = None) -> HardwareProfile:
    """A profile as a recipe defines it: `make_profile`, and a built-in's name only with the built-in's
    settings (`cpu1: {threads: 2}` was taken, every table saying "cpu1" of two threads: outside test K9).
    Job params may narrow a built-in (a lap's share of the cores), so this is the recipe's check only."""
    profile = make_profile(name, options)
    if name in BUILTIN and profile != BUILTIN[name]:
        raise PilotlabError(f"hardware.{name}: {name!r} is a built-in profile ({describe_profile(BUILTIN[name])}); "
                            f"give a profile of other settings a name of its own, e.g. {name}_mine")
    return profile


def describe_profile(profile: HardwareProfile) -> str:
    threads = "every core" if profile.threads is None else f"{profile.threads} thread{'s' * (profile.threads > 1)}"
    return f"{profile.device}, {threads}"


def profile_from_dict(data: dict[str, Any]) -> HardwareProfile:
    """The inverse of `HardwareProfile.as_dict` (job params carry profiles as dicts)."""
    options = {k: v for k, v in data.items() if k != "name"}
    return make_profile(data.get("name", "custom"), options or None)


def check_available(profile: HardwareProfile) -> None:
    """Raise NotApplicable when `profile` cannot run on this host."""
    if profile.device == "cuda":
        import torch
        if not torch.cuda.is_available():
            raise NotApplicable(f"hardware {profile.name!r} needs a CUDA GPU; this host has none "
                                f"(torch {torch.__version__})")
    if profile.threads is not None and profile.threads > cpu_count():
        raise NotApplicable(f"hardware {profile.name!r} asks for {profile.threads} threads; "
                            f"this host has {cpu_count()} cores")


def check_on_its_machine(profile: HardwareProfile, job: str) -> None:
    """A profile that stands for another machine (`worker_resource`) is timed only on the Dask worker that
    declares that resource: anywhere else its figures would be this host's, stored under the profile's key
    as that machine's, and a later run on the cluster would find them fresh (an outside test: a local
    run timed a JETSON profile on the laptop)."""
    if not profile.worker_resource:
        return
    held = dask_worker_resources()
    if held is not None and profile.worker_resource in held:
        return
    where = "outside Dask (the local executor)" if held is None else "on a Dask worker without that resource"
    raise PilotlabError(f"{job}: hardware {profile.name!r} stands for the machine of the Dask worker resource "
                        f"{profile.worker_resource!r}, and this job times it {where}: its figures would be this "
                        f"host's. Run the recipe with --executor dask --scheduler ADDRESS, with a worker started "
                        f"with --resources {profile.worker_resource}=1 on that machine")


def dask_worker_resources() -> dict[str, float] | None:
    """The resources of the Dask worker running this code; None outside one (or without Dask)."""
    try:
        from distributed import get_worker
        worker = get_worker()
    except (ImportError, ValueError):    # ValueError: not in a worker's task
        return None
    return dict(worker.state.total_resources)


def apply_profile(profile: HardwareProfile) -> None:
    """Set torch's thread count for this process (ONNX Runtime sessions take theirs from the profile)."""
    import torch
    check_available(profile)
    torch.set_num_threads(profile.cpu_threads)


# Device files a GPU driver creates (NVIDIA, NVIDIA Jetson, AMD ROCm, WSL2): without any of them
# torch cannot see a GPU, so the host fingerprint (needed to plan) is had without importing torch.
GPU_DEVICE_FILES = ("/dev/nvidia*", "/dev/nvhost-*", "/dev/nvgpu", "/dev/kfd", "/dev/dxg")


NVIDIA_GPU_INFO = "/proc/driver/nvidia/gpus/*/information"   # the driver's "Model: NVIDIA H100 80GB HBM3"
NVIDIA_MIG_INSTANCES = "/proc/driver/nvidia/capabilities/gpu*/mig/gi*"   # a GPU split into MIG instances


@cache
def gpu_name() -> str | None:
    """The first CUDA GPU's name as torch sees it; None without one (or with a torch built without CUDA).

    `plan` fingerprints the host, and torch's import and CUDA start-up cost seconds (7.6 s for the
    study's plan on an H100 host, 2026-11-26), so the name is read from the NVIDIA driver where that is
    the same answer: one GPU model, no device selection (CUDA_/NVIDIA_VISIBLE_DEVICES), no MIG instance
    (torch names the slice, "... MIG 1g.10gb"), and a torch built with CUDA. Else torch is asked."""
    if not any(glob.glob(pattern) for pattern in GPU_DEVICE_FILES):
        return None
    if _torch_cuda_build() is False:
        return None
    models = _nvidia_driver_models()
    selected = "CUDA_VISIBLE_DEVICES" in os.environ or "MIG" in os.environ.get("NVIDIA_VISIBLE_DEVICES", "")
    if len(models) == 1 and not selected and not glob.glob(NVIDIA_MIG_INSTANCES):
        return models.pop()
    import torch
    return torch.cuda.get_device_name(0) if torch.cuda.is_available() else None


def _nvidia_driver_models() -> set[str]:
    models = set()
    for info in glob.glob(NVIDIA_GPU_INFO):
        with contextlib.suppress(OSError):
            for line in Path(info).read_text().splitlines():
                key, _, value = line.partition(":")
                if key == "Model" and value.strip():
                    models.add(value.strip())
    return models


def _torch_cuda_build() -> bool | None:
    """Whether the installed torch was built with CUDA, read from its version file without importing
    it (`cuda: Optional[str] = None` in a CPU wheel); None when that cannot be told."""
    import importlib.util
    with contextlib.suppress(ImportError, ValueError, OSError, TypeError):
        spec = importlib.util.find_spec("torch")
        for folder in (spec.submodule_search_locations or []) if spec else []:
            for line in (Path(folder) / "version.py").read_text().splitlines():
                if line.startswith("cuda"):
                    return line.split("=", 1)[1].strip() != "None"
    return None


def host_fingerprint() -> dict[str, Any]:
    """What makes timings from this host comparable: CPU model, cores, GPU (None without one)."""
    return {"cpu": cpu_model(), "cores": cpu_count(), "machine": platform.machine(), "gpu": gpu_name()}


def describe_host(host: dict[str, Any]) -> str:
    """One line for reports: 'AMD EPYC, 2 cores, no GPU'."""
    gpu = host.get("gpu") or "no GPU"
    return f"{host.get('cpu')}, {host.get('cores')} cores, {gpu}"


def check_host(job: str, expected: dict[str, Any] | None) -> dict[str, Any]:
    """This host's fingerprint, refusing to time on another host than the one planned for (its
    timings would be filed under the wrong machine)."""
    host = host_fingerprint()
    if expected is not None and dict(expected) != host:
        raise PilotlabError(f"{job}: planned for host {describe_host(expected)} but running on "
                            f"{describe_host(host)}; plan the run on the machine that times it")
    return host
