"""Half precision: `bf16` and `fp16` (weights and compute in 16 bits; input and output stay float32,
the predictor casts at the boundary).

Only where the hardware computes in that precision natively: a CUDA GPU (fp16, bf16 on Ampere+),
or a CPU with AVX512-BF16/AMX (bf16) or AVX512-FP16/AMX-FP16 (fp16). Elsewhere torch emulates the
arithmetic (here fp16 ran 13× and bf16 6× slower than fp32 at batch 1), so the strategy is "not
applicable" unless `allow_emulated: true` asks for it anyway (useful to check accuracy).
Saved as frozen TorchScript in the target precision. Config: configs/half.py.
"""
from __future__ import annotations

import torch

from matrix.kinds import NotApplicable
from pilotlab.cpuinfo import NATIVE_CPU_FLAGS, native_cpu_dtype
from pilotlab.hardware import check_available
from pilotlab.strategies.configs.half import HalfConfig
from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.saving import save_torchscript


def bf16(config: HalfConfig, source: StrategySource) -> dict:
    return save_half(config, source, torch.bfloat16)


def fp16(config: HalfConfig, source: StrategySource) -> dict:
    return save_half(config, source, torch.float16)


def save_half(config: HalfConfig, source: StrategySource, dtype: torch.dtype) -> dict:
    device = source.hardware.device
    check_available(source.hardware)  # a CUDA target on a host without one: not applicable
    native = native_support(dtype, device)
    if not native and not config.allow_emulated:
        raise NotApplicable(f"{source.strategy}: {device} here has no native {dtype_name(dtype)} arithmetic "
                            f"(needs {' or '.join(sorted(NATIVE_CPU_FLAGS[dtype_name(dtype)]))} on a CPU, "
                            "or a CUDA GPU); torch would emulate it, slower than fp32")
    model = source.load_model().to(device=device, dtype=dtype)
    save_torchscript(model, source.out / "model.ts", source.input_shape, dtype=dtype, device=device)
    source.write(source.meta(format="torchscript", file="model.ts", runtime="torch",
                             dtype=dtype_name(dtype), device=device, extra={"native": native}))
    return {"native": native}


def native_support(dtype: torch.dtype, device: str) -> bool:
    if device == "cuda":
        return dtype == torch.float16 or torch.cuda.is_bf16_supported()
    return native_cpu_dtype(dtype_name(dtype))


def dtype_name(dtype: torch.dtype) -> str:
    return str(dtype).removeprefix("torch.")
