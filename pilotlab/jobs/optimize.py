"""The `optimize` job's handler: apply one strategy to one trained checkpoint
(params: pilotlab.specs.optimize.OptimizeSpec).

result: strategy, strategy_version, options (the full config), format, runtime, dtype, device, file,
size_mb, size_gz_mb (gzip-compressed), plus the strategy's own figures (sparsity, params, nonzero_params, layer_sparsity,
calibration_frames, finetune history, kept_channels, distinct_weights, native...)
artifacts: the artifact folder (model file + artifact.json), loadable with
pilotlab.predictor.load_predictor.
"""
from __future__ import annotations

import torch

from matrix.kinds import JobContext
from pilotlab.hardware import BUILTIN, profile_from_dict, worker_share
from pilotlab.specs.optimize import OptimizeSpec
from pilotlab.strategies.apply import StrategySource, apply_strategy


# The worker's share of the cores (matrix sets OMP_NUM_THREADS to it before the worker imports the kinds;
# every core outside a worker). A job before this one in the same worker may have left another count (a
# timing job sets its profile's, the training every core), and a fine-tune's figures follow the thread
# count, so they depended on the schedule (two cold study runs gave one fine-tuned strategy 1.6x and 2.3x
# the baseline's MSE). Not torch's count when this module is imported: that is the first optimize job's
# in the worker, after whatever ran before it (a quickstart whose fine-tune followed the training in one
# worker fine-tuned on 2 threads: another network, which left the road).
WORKER_THREADS = worker_share()


def run_optimize(ctx: JobContext) -> dict:
    spec: OptimizeSpec = ctx.spec
    source = strategy_source(ctx, profile_from_dict(spec.hardware) if spec.hardware else BUILTIN["cpu"])
    if "prepared" in ctx.deps:    # the network a prepare job made for this strategy and others
        source.prepared = (ctx.dep("prepared").artifacts, ctx.dep("prepared").result)
    return apply_strategy(spec.strategy, spec.options, source)


def strategy_source(ctx: JobContext, hardware) -> StrategySource:
    """What a strategy (or a preparation) starts from: the `model` dep's checkpoint and the `calibration`
    deps' training frames, on this worker's share of the cores."""
    if torch.get_num_threads() != WORKER_THREADS:   # only then: setting even the same count changed results
        torch.set_num_threads(WORKER_THREADS)
    calibration = ctx.dep_group("calibration") if "calibration" in ctx.deps else ()
    return StrategySource(checkpoint_path=ctx.dep("model").artifacts / "model.pt", out=ctx.out,
                          calibration_dirs=tuple(dep.artifacts for dep in calibration),
                          hardware=hardware, log=ctx.log,
                          progress=lambda done, total=None, what=None: ctx.progress(done, total, what))
