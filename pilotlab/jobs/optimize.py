"""The `optimize` job kind: apply one strategy to one trained checkpoint.

params:
    strategy   str   a name in pilotlab.strategies.STRATEGIES (baseline, dynamic_quant, ...)
    options    dict  the recipe's `strategies.<strategy>` section (unknown options are errors)
    hardware   dict  the target profile {"name", "device", "threads"} where the strategy depends on
                     it (fp16, bf16, tensorrt); optional, default the `cpu` profile
    host       dict  (optional) host fingerprint; only part of the key (the planner adds it for
                     hardware-dependent strategies), not read by the handler
deps:
    model        the train job; its artifacts hold `model.pt` (pilotlab.models.save_checkpoint)
    calibration  (optional group) frames jobs whose artifacts are FrameSet folders: the training
                 frames used to calibrate and fine-tune
result:
    strategy, strategy_version, options (the full config), format, runtime, dtype, device, file,
    size_mb, plus the strategy's own figures (sparsity, params, nonzero_params, layer_sparsity,
    calibration_frames, finetune history, kept_channels, distinct_weights, native...)
artifacts: the artifact folder (model file + artifact.json), loadable with
    pilotlab.predictor.load_predictor.

The code fingerprint is the shared strategy machinery plus the module of this job's strategy
(`code_for`), so editing one strategy reruns only its jobs.
"""
from __future__ import annotations

from matrix.kinds import JobContext, job_kind
from pilotlab.hardware import BUILTIN, profile_from_dict
from pilotlab.strategies import SHARED, strategy_modules
from pilotlab.strategies.registry import StrategySource, apply_strategy


def strategy_code(params) -> list[str]:
    return strategy_modules(params["strategy"])


@job_kind("optimize", code=[*SHARED, "pilotlab.training"], code_for=strategy_code)
def run_optimize(ctx: JobContext) -> dict:
    hardware = profile_from_dict(ctx.params["hardware"]) if ctx.params.get("hardware") else BUILTIN["cpu"]
    calibration = ctx.dep_group("calibration") if "calibration" in ctx.deps else ()
    source = StrategySource(checkpoint_path=ctx.dep("model").artifacts / "model.pt", out=ctx.out,
                            calibration_dirs=tuple(dep.artifacts for dep in calibration),
                            hardware=hardware, log=ctx.log,
                            progress=lambda done, total=None, what=None: ctx.progress(done, total, what))
    return apply_strategy(ctx.params["strategy"], ctx.params.get("options") or {}, source)
