"""Optimization strategies: each a frozen, versioned config plus a handler named by string, in
`STRATEGIES` (how to write one: registry.py).

Importing this package registers them all from their configs (`pilotlab.strategies.configs`),
importing no handler and so no torch, onnx, onnxruntime, torchao or tensorflow (nor numpy): planning
needs only names and configs. Apply one with `pilotlab.strategies.apply.apply_strategy(name, options,
source)`, which imports its handler's module; the artifact it writes is loaded with
`pilotlab.predictor.load_predictor`.
"""
from matrix.fingerprint import module_closure
from pilotlab.strategies import configs  # noqa: F401  (each config module registers its strategies)
from pilotlab.strategies.registry import (PREPARATIONS, STRATEGIES, full_options, make_strategy_config,  # noqa: F401
                                         preparation_for, register_strategy)

SHARED = ("pilotlab.strategies.registry", "pilotlab.strategies.apply", "pilotlab.strategies.artifact",
          "pilotlab.strategies.saving", "pilotlab.strategies.common", "pilotlab.strategies.fold", "pilotlab.strategies.edge",
          "pilotlab.strategies.configs.checks")


def strategy_modules(name: str) -> list[str]:
    """The modules implementing strategy `name` (its handler's and its config's) and the strategy
    modules they import (transitively), shared helpers excluded: the code whose edit must rerun this
    strategy's jobs (by name, read from the source, so naming it imports nothing)."""
    found = [module for root in STRATEGIES.get(name).modules
             for module in module_closure(root, "pilotlab.strategies", exclude=SHARED)]
    return list(dict.fromkeys(found))
