"""The `optimize` job: apply one strategy to one trained checkpoint.

deps: `model` (the train job: its model.pt) and `calibration` (a group of frames jobs: the training
frames, for calibration and fine-tuning). The code of an optimize job is the shared strategy
machinery plus the import closure of its own strategy's handler module and config module, so
editing one strategy reruns only its jobs.
"""
from __future__ import annotations

from typing import Any

from pydantic import Field

from matrix.fingerprint import module_closure
from matrix.kinds import register_kind
from pilotlab.specs.base import Spec
from pilotlab.strategies import STRATEGIES


class OptimizeSpec(Spec):
    strategy: str = Field(description="a registered strategy (baseline, dynamic_quant, ...)")
    options: dict[str, Any] = Field({}, description="the strategy's config fields (recipe strategies.<name>)")
    hardware: dict[str, Any] | None = Field(None, description="the target profile, where the strategy depends "
                                                              "on it (fp16, tensorrt); default: the cpu profile")
    host: dict[str, Any] | None = Field(None, description="host fingerprint: in the key only")


def strategy_modules() -> list[str]:
    """Every registered strategy's modules (handler and config): each job fingerprints only its own
    (`own_strategy`)."""
    return list(dict.fromkeys(module for _, entry in STRATEGIES.items() for module in entry.modules))


def own_strategy(params) -> list[str]:
    """The modules of the job's strategy (its handler's and its config's) and what they import within
    pilotlab (the strategies they build on included; the others left out)."""
    own = STRATEGIES.get(params["strategy"]).modules
    builds_on = {module for root in own for module in module_closure(root, "pilotlab.strategies")}
    others = [m for m in strategy_modules() if m not in own and m not in builds_on]
    found = [module for root in own for module in module_closure(root, "pilotlab", exclude=others)]
    return list(dict.fromkeys(found))


register_kind("optimize", "pilotlab.jobs.optimize:run_optimize", params=OptimizeSpec,
              code_for=own_strategy, code_exclude=strategy_modules)
