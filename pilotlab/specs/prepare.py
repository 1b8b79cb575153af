"""The `prepare` job: a network shaped and fine-tuned once on the torch side, for every strategy that
converts it (pilotlab.strategies.configs.prepare): structured_prune_int8 and structured_prune_litert_int8
with the same options fine-tune one network, not two.

deps: `model` (the train job) and `calibration` (its training frames), as the optimize jobs that load it.
result: the preparation's figures (kept_channels, macs, params..., finetune: the history).
artifacts: network.pt, the fine-tuned state dict (pilotlab.strategies.prepared).
"""
from __future__ import annotations

from typing import Any

from pydantic import Field

from matrix.fingerprint import module_closure
from matrix.kinds import register_kind
from pilotlab.specs.base import Spec
from pilotlab.strategies import PREPARATIONS


class PrepareSpec(Spec):
    preparation: str = Field(description="a registered preparation (channel_pruning, l1_pruning, magnitude_pruning)")
    options: dict[str, Any] = Field({}, description="its config's fields, read from the strategies that use it")


def preparation_code(params) -> list[str]:
    """The preparations' run-side module, the module of this preparation's shaper (its `target`: l1_pruning's
    is pilotlab.strategies.prune), and what they import within pilotlab (the fine-tuning loop)."""
    roots = ("pilotlab.strategies.prepared", PREPARATIONS.get(params["preparation"]).module)
    return list(dict.fromkeys(module for root in roots for module in module_closure(root, "pilotlab")))


register_kind("prepare", "pilotlab.jobs.prepare:run_prepare", params=PrepareSpec, code_for=preparation_code)
