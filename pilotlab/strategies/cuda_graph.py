"""`cuda_graph`: the network in fp16 (or fp32) on the GPU, replayed as a CUDA graph.

At batch 1 a small network on a GPU is bound by kernel launches, not arithmetic: PilotNet in eager
fp32 on an H100 took 0.72-0.95 ms a frame (two runs, 2026-11-26) for ~20 kernels and its copies. A
CUDA graph records the whole forward pass once per batch size and replays it with one launch (the
launch overhead that TensorRT's engines remove too; this needs nothing beyond torch). The artifact is
frozen TorchScript on the device, like `fp16`; the predictor captures a graph for each batch size it
is given (pilotlab.predictor.CudaGraphs). Only on a CUDA target; elsewhere "not applicable".
Config: configs/cuda.py.
"""
from __future__ import annotations

import torch

from pilotlab.strategies.apply import StrategySource
from pilotlab.strategies.common import require_cuda_target
from pilotlab.strategies.configs.cuda import CudaGraphConfig
from pilotlab.strategies.saving import save_torchscript

DTYPES = {"fp32": torch.float32, "fp16": torch.float16}


def cuda_graph(config: CudaGraphConfig, source: StrategySource) -> dict:
    require_cuda_target(source)
    dtype = DTYPES[config.precision]
    model = source.load_model().to(device="cuda", dtype=dtype)
    save_torchscript(model, source.out / "model.ts", source.input_shape, dtype=dtype, device="cuda")
    source.write(source.meta(format="torchscript", file="model.ts", runtime="torch",
                             dtype=str(dtype).removeprefix("torch."), device="cuda", extra={"cuda_graph": True}))
    return {"precision": config.precision}
