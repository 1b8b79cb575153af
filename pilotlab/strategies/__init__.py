"""Optimization strategies: each a frozen, versioned config plus a handler in `STRATEGIES`.

Importing this package registers them all. Apply one with `apply_strategy(name, options, source)`;
the artifact it writes is loaded with `pilotlab.predictor.load_predictor`.
"""
import ast
import importlib
import sys
from types import ModuleType

from pilotlab.strategies import (  # noqa: F401  (each module registers its strategies)
    baseline, cluster, cuda, half, onnx_runtime, prune, prune_quant, pt2e, structured_prune,
    structured_prune_int8, torchscript,
)
from pilotlab.strategies.registry import (  # noqa: F401
    STRATEGIES, StrategySource, apply_strategy, make_strategy_config, register_strategy,
)

SHARED = ("pilotlab.strategies.registry", "pilotlab.strategies.artifact", "pilotlab.strategies.common",
          "pilotlab.strategies.fold")


def strategy_modules(name: str) -> list[ModuleType]:
    """The module implementing strategy `name` and the strategy modules it imports (transitively),
    shared helpers excluded: the code whose edit must rerun this strategy's jobs."""
    found: list[str] = []
    pending = [STRATEGIES.get(name).module]
    while pending:
        module = pending.pop()
        if module in found or module in SHARED:
            continue
        found.append(module)
        pending += _strategy_imports(sys.modules.get(module) or importlib.import_module(module))
    return [sys.modules[m] for m in found]


def _strategy_imports(module: ModuleType) -> list[str]:
    tree = ast.parse(open(module.__file__).read())
    return [node.module for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("pilotlab.strategies.")]
