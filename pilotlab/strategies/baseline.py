"""`baseline`: the trained network as it is, fp32 eager PyTorch — the reference every ratio uses
(config: configs/baseline.py)."""
from __future__ import annotations

from pilotlab.strategies.common import save_float_model
from pilotlab.strategies.configs.baseline import BaselineConfig
from pilotlab.strategies.apply import StrategySource


def baseline(config: BaselineConfig, source: StrategySource) -> dict:
    # Kept as a pilotlab checkpoint run eagerly, as the 2022 study timed its PyTorch baseline; a
    # user's ONNX graph as it is, in ONNX Runtime.
    save_float_model(source.load_model(), source, "onnx" if source.imported == "onnx" else "checkpoint")
    return {}
