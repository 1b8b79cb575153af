"""An online evaluation: one brain, one circuit and direction, one or more runs from different start
points; metrics per run, their mean and spread, the trajectory data and pictures.

    spec = OnlineSpec(circuit="simple_circuit", repetitions=3, timing="replay")   # pilotlab.specs.online
    result = evaluate_online(brain, spec, out_dir, latency_ms=samples)   # samples: pilotlab.online.latency
    result["position_deviation_mae_m"], result["spread"]["position_deviation_mae_m"]["std"]

Files written into `out_dir`: trajectory.png (every run over the circuit, coloured by speed),
trajectory.npz and trajectory.csv (the samples of every run), and when asked camera.mp4 (the first
run's camera view) and frames/*.jpg (a few stills of it).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from pilotlab.circuits.circuit import Circuit
from pilotlab.online.bm_metrics import BM_METRICS, bm_run_metrics
from pilotlab.online.brains import Brain
from pilotlab.online.drive import drive
from pilotlab.online.media import CameraRecorder, plot_trajectories
from pilotlab.online.metrics import METRICS, aggregate, run_metrics
from pilotlab.online.perfect_lap import perfect_lap
from pilotlab.online.tolerance import cell_tolerance
from pilotlab.online.trajectory import Trajectory, save_csv, save_npz
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.specs.online import DriveSettings, LapSettings, OnlineSpec

STARTS = ("spread", "random")
ProgressFn = Callable[[float, float, str], None]   # (done, total, what)


def start_points(spec: LapSettings, length: float) -> list[float]:
    """Where each run starts, metres along the lap from the start line."""
    runs = spec.runs
    if spec.starts == "spread":
        return [i * length / runs for i in range(runs)]
    if spec.starts == "random":
        return [float(s) for s in np.random.default_rng(spec.seed).uniform(0.0, length, runs)]
    return [float(s) % length for s in spec.starts]


def make_env(spec: OnlineSpec, camera: bool, view=None, assets=None) -> DrivingEnv:
    """`view`: the brain's preprocessing, rendered directly instead of the camera image (sim.view);
    `assets`: the folder of BM's worlds, for a lap in one (`spec.world`)."""
    place = {"world": spec.world, "assets": assets} if spec.world else {"circuit": spec.circuit}
    return DrivingEnv(**place, direction=spec.direction,
                      camera=CameraSpec(width=spec.camera.width, height=spec.camera.height) if camera else None,
                      renderer=spec.renderer, control_period=spec.period_s, laps=spec.laps,
                      timeout_s=spec.timeout_s, stop_off_road=spec.stop_off_road, trapped_s=spec.trapped_s,
                      view=view)


def run_all(brain: Brain, spec: OnlineSpec, out: Path, progress: ProgressFn | None = None, latency_ms=None,
            assets=None) -> tuple[list[Trajectory], dict[str, Any], Circuit]:
    """Drive every repetition; returns the trajectories, the media written and the circuit driven."""
    wants_media = bool(spec.video or spec.camera_frames)
    # A network brain is given its preprocessed frame rendered directly (pilotlab.sim.view)
    env = make_env(spec, camera=brain.needs_camera or wants_media, view=getattr(brain, "view", None), assets=assets)
    recorder = CameraRecorder(out, control_hz=spec.control_hz, video_seconds=spec.video_length_s,
                              stills=spec.camera_frames) if wants_media else None
    trajectories = []
    try:
        brain.warm_up()
        starts = start_points(spec, env.circuit.length)
        for i, start in enumerate(starts):
            what = f"{brain.name} on {spec.world or spec.circuit} {spec.direction}, run {i + 1}/{len(starts)} from {start:.0f} m"
            report = None if progress is None else (lambda done, total, what=what: progress(done, total, what))
            trajectories.append(drive(env, brain, spec, start=start, seed=spec.seed + i, render=brain.needs_camera,
                                      on_frame=media_frames(env, recorder) if recorder and i == 0 else None,
                                      progress=report, latency_ms=latency_ms))
    finally:
        env.close()
        media = recorder.close() if recorder else {}
    return trajectories, media, env.circuit


def media_frames(env: DrivingEnv, recorder: CameraRecorder):
    """`drive`'s on_frame for the media: the full camera image, rendered only when the recorder keeps it
    (the brain may see only its view, or no image at all)."""
    def on_frame(image, info: dict[str, Any], command) -> None:
        if recorder.wants(info["sim_time"]):
            recorder(env.camera_image(), info, command)
    return on_frame


def evaluate_online(brain: Brain, spec: OnlineSpec, out: Path, progress: ProgressFn | None = None,
                    checkpoints=None, latency_ms=None, tolerance=None, assets=None,
                    tolerance_hint_ms: float | None = None) -> dict[str, Any]:
    """Drive, measure, and write the files; returns the result (see the module docstring). The
    BehaviorMetrics-compatible metrics are scored against `checkpoints` (default: the expert's lap on
    the same circuit and direction, `pilotlab.online.perfect_lap`); `latency_ms`: the samples the
    replay timing mode draws from; `tolerance` (a pilotlab.specs.online.ToleranceSpec): also search the cell's latency
    tolerance (pilotlab.online.tolerance) from the first run, starting at `tolerance_hint_ms` if given."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    if checkpoints is None:
        checkpoints = perfect_lap(spec.circuit, spec.direction)
    trajectories, media, circuit = run_all(brain, spec, out, progress, latency_ms, assets)
    runs = [{**run_metrics(t), **bm_run_metrics(t, checkpoints)} for t in trajectories]
    means, spread = aggregate(runs, METRICS + BM_METRICS)
    if tolerance is not None:
        # the search drives on the network's view, as the plain lap it starts from did (full frames
        # cost 2-4× more and made its laps differ from the plain one in the rendering)
        view = getattr(brain, "view", None)
        means |= cell_tolerance(make_env(spec, camera=brain.needs_camera, view=view, assets=assets), brain, spec,
                                tolerance, trajectories[0], checkpoints, latency_ms, progress, runs[0],
                                tolerance_hint_ms)
    save_npz(trajectories, out / "trajectory.npz")
    save_csv(trajectories, out / "trajectory.csv")
    title = picture_title(brain.name, spec, means, len(trajectories))
    plot_trajectories(circuit, trajectories, out / "trajectory.png", title=title)
    return {**means, "spread": spread, "runs": [run_summary(t, m) for t, m in zip(trajectories, runs)],
            "repetitions": len(trajectories), "brain": brain.name, "circuit": spec.circuit,
            **({"world": spec.world} if spec.world else {}),
            "direction": spec.direction, "circuit_length_m": round(circuit.length, 3), "laps": spec.laps,
            "perfect_lap_checkpoints": len(checkpoints),
            "timeout_s": trajectories[0].meta["timeout_s"], **_drive_settings(spec),
            "measured_inference_ms": float(np.mean([t.meta["measured_inference_ms"] for t in trajectories])),
            "trajectory": "trajectory.png", "trajectory_data": "trajectory.npz", "trajectory_csv": "trajectory.csv",
            **media, "wall_seconds": round(time.perf_counter() - started, 3)}


def run_summary(trajectory: Trajectory, metrics: dict[str, Any]) -> dict[str, Any]:
    meta = trajectory.meta
    return {"start_m": round(meta["start_m"], 3), "termination": meta["termination"],
            "sim_seconds": round(meta["sim_seconds"], 3), "wall_seconds": round(meta["wall_seconds"], 3),
            "iterations": len(trajectory.decisions), **{k: v for k, v in metrics.items() if v is not None}}


def _drive_settings(settings: DriveSettings) -> dict[str, Any]:
    values = {name: getattr(settings, name) for name in DriveSettings.model_fields}
    return {k: v for k, v in values.items() if v is not None}


def picture_title(name: str, spec: OnlineSpec, means: dict[str, Any], runs: int) -> str:
    settings = spec
    # a BM world's name: its variants (white_line, no_sun) share the circuit, and their pictures read alike
    place = f"in BM's world {spec.world}" if spec.world else f"on {spec.circuit}"
    first = f"{name} {place} ({spec.direction}), {settings.timing} timing at {settings.control_hz:g} Hz"
    if settings.extra_latency_ms:
        first += f" +{settings.extra_latency_ms:g} ms"
    laps = "lap completed" if means.get("lap_completed") else "lap not completed"
    if runs > 1:
        laps = f"{runs} runs, " + ("every lap completed" if means.get("lap_completed") else "not every lap completed")
    figures = [laps]
    for key, label, unit in (("lap_seconds", "lap", " s"), ("percentage_completed", "done", " %"),
                             ("average_speed", "speed", " m/s"), ("position_deviation_mae_m", "MAE", " m"),
                             ("brain_frequency_sim_hz", "brain", " Hz")):
        if means.get(key) is not None:
            figures.append(f"{label} {means[key]:.3g}{unit}")
    return first + "\n" + ", ".join(figures) + (" (means)" if runs > 1 else "")
