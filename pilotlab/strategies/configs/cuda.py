"""The configs of `tensorrt` and `cuda_graph` (their handlers: pilotlab/strategies/cuda.py and cuda_graph.py)."""
from __future__ import annotations

from dataclasses import dataclass

from pilotlab.errors import PilotlabError
from pilotlab.strategies.registry import register_strategy

PRECISIONS = ("fp32", "fp16", "int8")


@dataclass(frozen=True)
class TensorRTConfig:
    version: int = 2                 # 2: `precision` (fp32, fp16, int8) replaces `fp16: true|false`
    precision: str = "fp16"          # the engine's precision, as the study's TF-TRT rows (FP32, FP16, INT8)
    calibration_frames: int = 512    # int8: training frames the calibrator sees

    def __post_init__(self) -> None:
        if self.precision not in PRECISIONS:
            raise PilotlabError(f"precision: {self.precision!r} is not one of {', '.join(PRECISIONS)}")
        if self.calibration_frames < 1:
            raise PilotlabError(f"calibration_frames: {self.calibration_frames} must be ≥ 1")


register_strategy("tensorrt", TensorRTConfig, "pilotlab.strategies.cuda:tensorrt", hardware_dependent=True)


@dataclass(frozen=True)
class CudaGraphConfig:
    version: int = 1
    precision: str = "fp16"          # fp16 or fp32: the network's weights and compute on the GPU

    def __post_init__(self) -> None:
        if self.precision not in ("fp32", "fp16"):
            raise PilotlabError(f"precision: {self.precision!r} is not one of fp32, fp16")


register_strategy("cuda_graph", CudaGraphConfig, "pilotlab.strategies.cuda_graph:cuda_graph", hardware_dependent=True)
