"""The `online` job kind: a closed-loop evaluation of one brain on one circuit in the simulator, with
BehaviorMetrics' metrics. Registered exclusive (timing: nothing runs beside it) and asking Dask for a
GPU when its hardware profile is a CUDA one.

deps:
    artifact   (optional) the optimize job: its artifacts folder is the artifact the brain runs
               through `pilotlab.predictor.load_predictor`. Without it, `brain` names a reference brain.
params (only `circuit` is required; defaults in brackets):
    brain             str    ["network" with an artifact] "explicit" (OpenCV line follower) | "expert"
                             (ground truth): the reference rows
    brain_options     dict   [{}] fields of the reference brain's config (ExplicitBrainConfig, ExpertConfig)
    hardware          dict   [{"name": "cpu"}] the profile {"name", "device", "threads"}; a CUDA profile on a
                             host without a GPU is not applicable
    host              dict   (optional) pilotlab.hardware.host_fingerprint() the planner expects; another
                             host is an error, so timings are never filed under another machine
    circuit           str    circuit name (built-in, ./circuits/NAME.csv, $PILOTLAB_CIRCUITS) or CSV path
    direction         str    ["cw"] | "ccw"
    laps              float  [1] laps to drive
    timing            str    ["latency"] | "lockstep" | "realtime" (see pilotlab.online.drive)
    control_hz        float  [20] brain iterations per simulated second when the brain keeps up
                             (BehaviorMetrics' 50 ms cycle)
    timeout_s         float  [the circuit's BehaviorMetrics timeout × laps: simple_circuit 82.5 s, ...]
    repetitions       int    [1, or the length of `starts`] runs, each from its own start point
    starts            str|list  ["spread"]: evenly around the lap (the first at the start line) |
                             "random" (from `seed`) | metres along the lap, one per run
    seed              int    [0]
    extra_latency_ms  float  [0] artificial latency added to every brain iteration (a slower network)
    fixed_inference_ms float [null] latency mode: charge this instead of the measured brain time (exactly
                             reproducible runs; "what if it took X ms")
    frame_interval_ms float  [the artifact's preprocess "frame_interval_s", else 100] temporal models: the
                             time between the stacked frames (that of consecutive training frames)
    stop_off_road     bool   [true] stop a run when the car's centre leaves the road
    trapped_s         float  [10] stop a run after this long without 1 m of progress
    camera            dict   [{"width": 640, "height": 480}] the camera image (as the record job's)
    renderer          str    ["ground"] | "pybullet"
    video             bool   [false] write camera.mp4, the first run's camera view
    video_seconds     float  [20] length of that video (simulated seconds)
    camera_frames     int    [4] JPEG stills of the first run's camera view (0: none)
result:
    the ONLINE metrics of pilotlab.columns (lap_completed, completed_distance_m, percentage_completed,
    lap_seconds, average_speed, position_deviation_mae_m, position_deviation_total_m,
    brain_frequency_sim_hz, brain_frequency_real_hz, mean_inference_ms, real_time_factor, suddenness,
    off_road_events): the mean over the runs (lap_seconds over the completed laps; lap_completed true
    only when every run completed); spread {metric: {std, min, max, runs}} (lap_completed:
    {completed, runs}); runs [{start_m, termination, sim_seconds, wall_seconds, iterations, metrics}];
    repetitions, brain, strategy (the artifact's, or the reference brain's name), hardware (profile),
    host, circuit, direction, circuit_length_m, laps, timeout_s, timing, control_hz, extra_latency_ms,
    fixed_inference_ms (if set), measured_inference_ms (the real mean, without artificial latency),
    wall_seconds; and the files, relative to the artifacts folder: trajectory ("trajectory.png"),
    trajectory_data ("trajectory.npz"), trajectory_csv ("trajectory.csv"), video ("camera.mp4", if
    asked), camera_frames (["frames/camera_012.00s.jpg", ...]).
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from matrix.kinds import JobContext, job_kind
from pilotlab.errors import PilotlabError
from pilotlab.hardware import check_available, describe_host, host_fingerprint, profile_from_dict

if TYPE_CHECKING:  # the simulator, OpenCV, torch, matplotlib: imported by the handler, not to plan
    from pilotlab.online import brains, evaluate

CODE = ["pilotlab.online.brains", "pilotlab.online.drive", "pilotlab.online.evaluate", "pilotlab.online.media",
        "pilotlab.online.metrics", "pilotlab.online.trajectory", "pilotlab.predictor", "pilotlab.strategies.artifact",
        "pilotlab.data.preprocess", "pilotlab.data.frames", "pilotlab.sim.env", "pilotlab.sim.car",
        "pilotlab.sim.camera", "pilotlab.sim.render", "pilotlab.sim.world", "pilotlab.sim.expert",
        "pilotlab.sim.explicit", "pilotlab.circuits.circuit", "pilotlab.circuits.draw", "pilotlab.circuits.geometry",
        "pilotlab.circuits.registry"]
DEFAULTS: dict[str, Any] = {
    "brain": None, "brain_options": {}, "hardware": {"name": "cpu"}, "host": None, "circuit": None, "direction": "cw",
    "laps": 1.0, "timing": "latency", "control_hz": 20.0, "timeout_s": None, "repetitions": None,
    "starts": "spread", "seed": 0, "extra_latency_ms": 0.0, "fixed_inference_ms": None, "frame_interval_ms": None,
    "stop_off_road": True, "trapped_s": 10.0, "camera": {"width": 640, "height": 480}, "renderer": "ground",
    "video": False, "video_seconds": 20.0, "camera_frames": 4}


def settings(ctx: JobContext) -> dict[str, Any]:
    unknown = sorted(set(ctx.params) - set(DEFAULTS))
    if unknown:
        raise PilotlabError(f"{ctx.name}: the online job has no param(s) {', '.join(unknown)}; "
                            f"known: {', '.join(sorted(DEFAULTS))}")
    if not ctx.params.get("circuit"):
        raise PilotlabError(f"{ctx.name}: the online job needs a 'circuit' param")
    return {**DEFAULTS, **ctx.params}


def online_spec(p: Mapping[str, Any]) -> evaluate.OnlineSpec:
    from pilotlab.online import drive, evaluate
    starts = p["starts"] if isinstance(p["starts"], str) else tuple(p["starts"])
    repetitions = p["repetitions"] or (1 if isinstance(starts, str) else len(starts))
    camera_size = {**DEFAULTS["camera"], **(p["camera"] or {})}
    timing = drive.DriveSettings(timing=p["timing"], control_hz=float(p["control_hz"]),
                                 extra_latency_ms=float(p["extra_latency_ms"]),
                                 fixed_inference_ms=p["fixed_inference_ms"])
    return evaluate.OnlineSpec(
        circuit=p["circuit"], direction=p["direction"], laps=float(p["laps"]), timeout_s=p["timeout_s"],
        repetitions=int(repetitions), starts=starts, seed=int(p["seed"]), stop_off_road=bool(p["stop_off_road"]),
        trapped_s=float(p["trapped_s"]), camera_width=int(camera_size["width"]),
        camera_height=int(camera_size["height"]), renderer=p["renderer"], drive=timing,
        video_seconds=float(p["video_seconds"]) if p["video"] else None, camera_frames=int(p["camera_frames"]))


def make_brain(ctx: JobContext, p: Mapping[str, Any], profile) -> tuple[brains.Brain, str]:
    """The brain and the strategy name of the report row."""
    from pilotlab import predictor
    from pilotlab.online import brains
    if "artifact" in ctx.deps:
        if p["brain"] not in (None, "network"):
            raise PilotlabError(f"{ctx.name}: has an artifact dependency and brain={p['brain']!r}; a reference brain "
                                "takes no artifact (drop one of them)")
        artifact = ctx.dep("artifact")
        interval = p["frame_interval_ms"] / 1000 if p["frame_interval_ms"] else None
        brain = brains.NetworkBrain(predictor.load_predictor(artifact.artifacts, profile, spin=False),
                                   frame_interval_s=interval)
        return brain, artifact.result.get("strategy", brain.name)
    if p["brain"] in (None, "network"):
        names = ", ".join(brains.REFERENCE_BRAINS.names())
        raise PilotlabError(f"{ctx.name}: give the online job an 'artifact' dependency (an optimize job) or "
                            f"brain: one of {names}")
    return brains.make_reference_brain(p["brain"], p["brain_options"]), p["brain"]


def check_host(ctx: JobContext, expected: Mapping[str, Any] | None) -> dict[str, Any]:
    host = host_fingerprint()
    if expected is not None and dict(expected) != host:
        raise PilotlabError(f"{ctx.name}: planned for host {describe_host(expected)} but running on "
                            f"{describe_host(host)}; plan the run on the machine that times it")
    return host


def gpu_resources(params: Mapping[str, Any]) -> dict[str, float]:
    hardware = params.get("hardware") or {}
    return {"GPU": 1} if hardware.get("device") == "cuda" else {}


@job_kind("online", code=CODE, exclusive=True, resources_for=gpu_resources)
def run_online(ctx: JobContext) -> dict[str, Any]:
    import cv2
    from pilotlab.online import evaluate
    p = settings(ctx)
    spec = online_spec(p)
    profile = profile_from_dict(p["hardware"])
    check_available(profile)
    cv2.setNumThreads(profile.cpu_threads)  # the explicit brain's and preprocessing's OpenCV calls
    host = check_host(ctx, p["host"])
    brain, strategy = make_brain(ctx, p, profile)
    ctx.log.info("%s on %s %s: %s timing at %g Hz, %d run(s)", strategy, spec.circuit, spec.direction,
                 spec.drive.timing, spec.drive.control_hz, spec.repetitions)
    result = evaluate.evaluate_online(brain, spec, ctx.out, progress=lambda done, total, what: ctx.progress(
        done, total, what))
    ctx.log.info("%s: %s", strategy, ", ".join(f"{run['termination']} after {run['sim_seconds']:.1f} s"
                                               for run in result["runs"]))
    return {**result, "strategy": strategy, "hardware": profile.as_dict(), "host": host}
