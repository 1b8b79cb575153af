"""What this host's CPU is and can do, read from /proc/cpuinfo (no torch import): its model name for the
host fingerprint, and its flags, which say whether it computes 16-bit floats natively (the half-precision
strategies and the training's bf16 mixed precision ask). A module of its own so that training, which
asks, does not depend on pilotlab.hardware's timing profiles (editing those reruns no training)."""
from __future__ import annotations

import platform
from functools import cache
from pathlib import Path


@cache
def cpu_model() -> str:
    return _cpuinfo_field("model name") or platform.processor() or platform.machine()


@cache
def cpu_flags() -> frozenset[str]:
    return frozenset((_cpuinfo_field("flags") or "").split())


def _cpuinfo_field(key: str) -> str | None:
    """The first value of `key` in /proc/cpuinfo (None where it, or the file, is missing)."""
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith(key):
                return line.split(":", 1)[1].strip()
    return None


# CPU flags of native 16-bit float arithmetic: without one torch emulates it, slower than fp32
NATIVE_CPU_FLAGS = {"bfloat16": frozenset({"avx512_bf16", "amx_bf16"}),
                    "float16": frozenset({"avx512_fp16", "amx_fp16"})}


def native_cpu_dtype(dtype: str) -> bool:
    """Whether this CPU computes `dtype` ("bfloat16" or "float16") natively."""
    return bool(NATIVE_CPU_FLAGS[dtype] & cpu_flags())
