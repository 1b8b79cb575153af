"""Optimization strategies: each a frozen, versioned config plus a handler in `STRATEGIES`.

Importing this package registers them all (without importing torch: see registry.py). Apply one
with `apply_strategy(name, options, source)`; the artifact it writes is loaded with
`pilotlab.predictor.load_predictor`.
"""
from matrix.fingerprint import module_closure
from pilotlab.strategies import (  # noqa: F401  (each module registers its strategies)
    baseline, cluster, cuda, half, litert, mot, onnx_runtime, prune, prune_quant, pt2e,
    structured_prune, structured_prune_int8, structured_prune_xnnpack, torchscript,
)
from pilotlab.strategies.registry import (  # noqa: F401
    STRATEGIES, StrategySource, apply_strategy, make_strategy_config, register_strategy,
)

SHARED = ("pilotlab.strategies.registry", "pilotlab.strategies.artifact", "pilotlab.strategies.common",
          "pilotlab.strategies.fold", "pilotlab.strategies.edge")


def strategy_modules(name: str) -> list[str]:
    """The module implementing strategy `name` and the strategy modules it imports (transitively),
    shared helpers excluded: the code whose edit must rerun this strategy's jobs (by name, read from
    the source, so naming it imports nothing)."""
    return module_closure(STRATEGIES.get(name).module, "pilotlab.strategies", exclude=SHARED)
