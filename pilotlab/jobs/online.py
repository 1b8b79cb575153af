"""The `online` job's handler (params: pilotlab.specs.online.OnlineSpec): a closed-loop
evaluation of one brain on one circuit in the simulator, with BehaviorMetrics' metrics.

result:
    the ONLINE metrics of pilotlab.columns (lap_completed, completed_distance_m, percentage_completed,
    lap_seconds, average_speed, position_deviation_mae_m, position_deviation_total_m,
    brain_frequency_sim_hz, brain_frequency_real_hz, mean_inference_ms, real_time_factor, suddenness,
    off_road_events): the mean over the runs (lap_seconds over the completed laps; lap_completed true
    only when every run completed); spread {metric: {std, min, max, runs}} (lap_completed:
    {completed, runs}); runs [{start_m, termination, sim_seconds, wall_seconds, iterations, metrics}];
    repetitions, brain, strategy (the artifact's, or the reference brain's name: for a brain the user
    wrote, its user_brain.name), hardware (profile),
    host, hostname (the host that drove it), circuit, direction, circuit_length_m, laps, timeout_s, timing, control_hz, extra_latency_ms,
    fixed_inference_ms (if set), measured_inference_ms (the real mean, without artificial latency),
    wall_seconds; unstable ({"latency_ms": why}, where a lap timed on this host's clock shared the cores
    its brain needed with other processes: disturbed_lap); BehaviorMetrics' metrics
    (pilotlab.columns.BEHAVIORMETRICS, bm_*) against the
    expert's perfect lap, and perfect_lap_checkpoints; in replay timing latency_source,
    replayed_latency_ms, replayed_latency_p90_ms, replayed_latency_samples (and latency_scale when
    scaled); with tolerance: latency_tolerance_ms, tolerance_at_least, tolerance_fixed_ms,
    tolerance_laps, tolerance_laps_driven (pilotlab.online.tolerance), and tolerance_hint_ms and
    tolerance_hint_from when the search started at a neighbour cell's tolerance (the dependency
    `tolerance_hint`: the same brain's lap on the recipe's shortest circuit); and the files, relative to the
    artifacts folder: trajectory ("trajectory.png"), trajectory_data ("trajectory.npz"), trajectory_csv
    ("trajectory.csv"), video ("camera.mp4", if asked), camera_frames (["frames/camera_012.00s.jpg", ...]).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from matrix.hostlock import host_name
from matrix.kinds import JobContext
from pilotlab import predictor, timing, usercode
from pilotlab.errors import PilotlabError
from pilotlab.hardware import check_available, check_host, check_on_its_machine, profile_from_dict, within_share
from pilotlab.online import brains, evaluate
from pilotlab.online.latency import TimingSource, describe
from pilotlab.online.perfect_lap import perfect_lap
from pilotlab.specs.online import OnlineSpec, timed_live
from pilotlab.specs.record import with_circuit_file
from pilotlab.worlds.assets import world_assets


def make_brain(ctx: JobContext, spec: OnlineSpec, profile) -> tuple[brains.Brain, str]:
    """The brain and the strategy name of the report row."""
    if "artifact" in ctx.deps:
        if spec.brain != "network":
            raise PilotlabError(f"{ctx.name}: has an artifact dependency and brain={spec.brain!r}; a reference "
                                "brain takes no artifact (drop one of them)")
        artifact = ctx.dep("artifact")
        interval = spec.frame_interval_ms / 1000 if spec.frame_interval_ms else None
        brain = brains.NetworkBrain(predictor.load_predictor(artifact.artifacts, profile, spin=False),
                                    frame_interval_s=interval)
        return brain, artifact.result.get("strategy", brain.name)
    if spec.brain == "network":
        names = ", ".join(brains.REFERENCE_BRAINS.names())
        raise PilotlabError(f"{ctx.name}: give the online job an 'artifact' dependency (an optimize job) or "
                            f"brain: one of {names}, or user (with user_brain)")
    if spec.brain == "user":
        mine = spec.user_brain
        source = ctx.inputs.get("brain_source")
        base = usercode.base_of(mine.spec, source) if source is not None else Path(mine.base)
        return brains.UserBrain(mine.spec, base, name=mine.name), mine.name
    return brains.make_reference_brain(spec.brain, reference_options(ctx, spec)), spec.brain


def reference_options(ctx: JobContext, spec: OnlineSpec) -> dict[str, Any]:
    """A reference brain's options; in a BM world the expert drives BM's small F1 (its wheelbase and pace),
    and the explicit brain looks where BM's camera sees the line and follows the world's line colour
    (white in *_white_line), unless the recipe says otherwise."""
    if spec.world is None or spec.brain not in ("explicit", "expert"):
        return spec.brain_options
    if spec.brain == "expert":
        from pilotlab.sim.expert import BM_EXPERT
        return {**BM_EXPERT, **spec.brain_options}
    from pilotlab.sim.explicit import bm_world_options
    from pilotlab.worlds import load_world
    assets, name = world_assets(ctx.inputs)
    return {**bm_world_options(load_world(name, assets).line_colour), **spec.brain_options}


CHARGED_NOTHING = "none: a reference brain is charged only the injected latency"
NOT_CHARGED = ("mean_inference_ms", "bm_mean_inference_ms")   # a lap's inference time, as charged to it


def without_uncharged_inference(result: dict[str, Any]) -> dict[str, Any]:
    """A reference brain's lap replayed charges it no inference time: the lap has none to report (its
    0 read as a measured 0 ms in the report's tables); its own computation is measured_inference_ms."""
    for part in (result, result.get("spread") or {}, *(result.get("runs") or [])):
        part.update({name: None for name in NOT_CHARGED if name in part})
    return result


def replayed_latency(ctx: JobContext, spec: OnlineSpec, brain) -> tuple[np.ndarray | None, dict[str, Any]]:
    """The latency samples the replay timing mode draws from (None in the other modes), and what the
    result says of them. Reference brains are charged nothing but the injected latency."""
    if spec.timing != "replay" or spec.fixed_inference_ms is not None:
        return None, {}
    if "artifact" not in ctx.deps:
        return np.zeros(1), describe(np.zeros(1), CHARGED_NOTHING)
    dep = lambda role: (ctx.dep(role).artifacts, ctx.dep(role).result) if role in ctx.deps else None
    source = TimingSource(timing=dep("timing"), latency_file=ctx.inputs.get("latency_file"),
                          model=spec.latency_for.get("model"), strategy=spec.latency_for.get("strategy", brain.name),
                          scale_to_ms=spec.latency_scale_to_ms, reference=dep("scale_reference"))
    return source.samples()


def tolerance_hint(ctx: JobContext) -> dict[str, Any]:
    """Where this cell's tolerance search starts: the tolerance its `tolerance_hint` dependency found
    (the same brain on the recipe's shortest circuit: pilotlab.planning.laps), and that lap's name;
    {} without one, or when that lap found none (lost with nothing injected)."""
    if "tolerance_hint" not in ctx.deps:
        return {}
    neighbour = ctx.dep("tolerance_hint")
    found = neighbour.result.get("latency_tolerance_ms")
    return {} if found is None else {"tolerance_hint_ms": float(found), "tolerance_hint_from": neighbour.name}


def disturbed_lap(before: timing.Snapshot, profile, mode: str) -> str | None:
    """Why a lap timed on this host's clock (measured, realtime) does not show this machine's own speed:
    other processes took cores its brain needed (it runs alone among pilotlab's jobs, not beside a
    user's), so its latencies, and the driving that rests on them, were inflated. None when quiet."""
    load = timing.load_between(before, timing.snapshot())
    cores, needs = len(timing.our_cpus()), profile.cpu_threads
    # the timing jobs' rule for other processes' cores (a lap's own CPU share says nothing: it may sleep)
    if load.others_cores is None or timing.block_is_quiet(load, needs, cores, timing.Limits(min_cpu_per_wall=0.0)):
        return None
    return (f"other processes used {load.others_cores:.2f} of {cores} cores during this lap, beside the {needs} its "
            f"{mode} timing needs: its inference times, and the driving that rests on them, are not this "
            "machine's own (replay timing does not depend on the load)")


def run_online(ctx: JobContext) -> dict[str, Any]:
    spec: OnlineSpec = with_circuit_file(ctx.spec, ctx.inputs)
    profile = profile_from_dict(spec.hardware)
    check_available(profile)
    if timed_live(ctx.params):   # a replayed lap replays that machine's timings anywhere
        check_on_its_machine(profile, ctx.name)
    # a lap not timed on this host's clock runs beside another job: its brain keeps to its share of cores
    compute = profile if timed_live(ctx.params) else within_share(profile)
    cv2.setNumThreads(compute.cpu_threads)  # the explicit brain's and preprocessing's OpenCV calls
    host = check_host(ctx.name, spec.host)
    brain, strategy = make_brain(ctx, spec, compute)
    ctx.log.info("%s on %s %s: %s timing at %g Hz, %d run(s)", strategy, spec.world or spec.circuit, spec.direction,
                 spec.timing, spec.control_hz, spec.runs)
    samples, replayed = replayed_latency(ctx, spec, brain)
    checkpoints = perfect_lap(spec.circuit, spec.direction, cache=ctx.cache / "perfect_laps")
    hint = tolerance_hint(ctx)
    before = timing.snapshot()
    result = evaluate.evaluate_online(brain, spec, ctx.out, progress=lambda done, total, what: ctx.progress(
        done, total, what), latency_ms=samples, tolerance=spec.tolerance, checkpoints=checkpoints,
        assets=world_assets(ctx.inputs)[0], tolerance_hint_ms=hint.get("tolerance_hint_ms"))
    result |= replayed | (hint if spec.tolerance is not None else {})
    if timed_live(ctx.params) and (reason := disturbed_lap(before, compute, spec.timing)):
        result["unstable"] = {"latency_ms": reason}   # the report marks the lap ⚠ and draws nothing from it
    if replayed.get("latency_source") == CHARGED_NOTHING:
        result = without_uncharged_inference(result)
    ctx.log.info("%s: %s", strategy, ", ".join(f"{run['termination']} after {run['sim_seconds']:.1f} s"
                                               for run in result["runs"]))
    return {**result, "strategy": strategy, "hardware": profile.as_dict(), "host": host, "hostname": host_name()}
