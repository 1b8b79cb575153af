"""The `prepare` job's handler (params: pilotlab.specs.prepare.PrepareSpec): shape and fine-tune a network
once for the strategies that convert it (pilotlab.strategies.prepared)."""
from __future__ import annotations

from matrix.kinds import JobContext
from pilotlab.hardware import BUILTIN
from pilotlab.jobs.optimize import strategy_source
from pilotlab.specs.base import build_config
from pilotlab.specs.prepare import PrepareSpec
from pilotlab.strategies.apply import check_takes, on_user_model
from pilotlab.strategies.configs.prepare import PREPARATIONS
from pilotlab.strategies.prepared import prepare, save_prepared


def run_prepare(ctx: JobContext) -> dict:
    spec: PrepareSpec = ctx.spec
    entry = PREPARATIONS.get(spec.preparation)
    config = build_config(entry.config_cls, spec.options, f"preparations.{spec.preparation}")
    source = strategy_source(ctx, BUILTIN["cpu"])
    check_takes(spec.preparation, source)     # a user's ONNX graph, or a network it cannot rewrite: n/a
    model, figures = on_user_model(spec.preparation, source, lambda: prepare(entry, config, source))
    save_prepared(model, ctx.out)
    return {"preparation": spec.preparation, "options": entry.options_of(config), **figures}
