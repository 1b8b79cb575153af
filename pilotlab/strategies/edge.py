"""What the edge-runtime strategies (LiteRT) share: they run only where their optional
packages are installed (`pip install -e '.[edge]'`), and otherwise say so as "not applicable"
instead of failing the run; their artifacts run on the CPU only (XNNPACK), which the predictor
checks."""
from __future__ import annotations

import importlib.util

from matrix.kinds import NotApplicable
from pilotlab.strategies.registry import StrategySource

EXTRA = "pip install -e '.[edge]'"
LITERT_CONVERTER = ("tensorflow", "tf_keras", "onnx2tf", "onnx_graphsurgeon", "ai_edge_litert")


def missing(modules: tuple[str, ...]) -> list[str]:
    return [name for name in modules if importlib.util.find_spec(name) is None]


def require(source: StrategySource, modules: tuple[str, ...]) -> None:
    """NotApplicable unless every module is importable here (found without importing it: planning
    stays light)."""
    absent = missing(modules)
    if absent:
        raise NotApplicable(f"{source.strategy} needs {', '.join(absent)}, not installed here ({EXTRA})")
