"""An online evaluation: one brain, one circuit and direction, one or more runs from different start
points; metrics per run, their mean and spread, the trajectory data and pictures.

    spec = OnlineSpec(circuit="simple_circuit", repetitions=3, drive=DriveSettings(timing="latency"))
    result = evaluate_online(brain, spec, out_dir)
    result["position_deviation_mae_m"], result["spread"]["position_deviation_mae_m"]["std"]

Files written into `out_dir`: trajectory.png (every run over the circuit, coloured by speed),
trajectory.npz and trajectory.csv (the samples of every run), and when asked camera.mp4 (the first
run's camera view) and frames/*.jpg (a few stills of it).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pilotlab.circuits import Circuit
from pilotlab.errors import PilotlabError
from pilotlab.online.brains import Brain
from pilotlab.online.drive import DriveSettings, drive
from pilotlab.online.media import CameraRecorder, plot_trajectories
from pilotlab.online.metrics import aggregate, run_metrics
from pilotlab.online.trajectory import Trajectory, save_csv, save_npz
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv

STARTS = ("spread", "random")
ProgressFn = Callable[[float, float, str], None]   # (done, total, what)


@dataclass(frozen=True)
class OnlineSpec:
    circuit: str
    direction: str = "cw"
    laps: float = 1.0
    timeout_s: float | None = None          # default: the circuit's BehaviorMetrics timeout × laps
    repetitions: int = 1
    starts: str | tuple[float, ...] = "spread"   # "spread" | "random" | metres along the lap, one per run
    seed: int = 0
    stop_off_road: bool = True
    trapped_s: float = 10.0
    camera_width: int = 640                 # the record job's camera: what the network was trained on
    camera_height: int = 480
    renderer: str = "ground"
    drive: DriveSettings = field(default_factory=DriveSettings)
    video_seconds: float | None = None      # a video of the first run's first seconds (None: no video)
    camera_frames: int = 0                  # stills of the first run
    version: int = 1

    def start_points(self, length: float) -> list[float]:
        """Where each run starts, metres along the lap from the start line."""
        if self.repetitions < 1:
            raise PilotlabError(f"repetitions must be at least 1, got {self.repetitions}")
        if self.starts == "spread":
            return [i * length / self.repetitions for i in range(self.repetitions)]
        if self.starts == "random":
            return [float(s) for s in np.random.default_rng(self.seed).uniform(0.0, length, self.repetitions)]
        if isinstance(self.starts, str):
            raise PilotlabError(f"starts {self.starts!r}: give 'spread', 'random' or a list of metres")
        if len(self.starts) != self.repetitions:
            raise PilotlabError(f"starts lists {len(self.starts)} point(s) but repetitions is {self.repetitions}; "
                                "give one start point per repetition")
        return [float(s) % length for s in self.starts]


def make_env(spec: OnlineSpec, camera: bool) -> DrivingEnv:
    return DrivingEnv(spec.circuit, direction=spec.direction,
                      camera=CameraSpec(width=spec.camera_width, height=spec.camera_height) if camera else None,
                      renderer=spec.renderer, control_period=spec.drive.period_s, laps=spec.laps,
                      timeout_s=spec.timeout_s, stop_off_road=spec.stop_off_road, trapped_s=spec.trapped_s)


def run_all(brain: Brain, spec: OnlineSpec, out: Path, progress: ProgressFn | None = None
            ) -> tuple[list[Trajectory], dict[str, Any], Circuit]:
    """Drive every repetition; returns the trajectories, the media written and the circuit driven."""
    wants_media = bool(spec.video_seconds or spec.camera_frames)
    env = make_env(spec, camera=brain.needs_camera or wants_media)
    recorder = CameraRecorder(out, control_hz=spec.drive.control_hz, video_seconds=spec.video_seconds,
                              stills=spec.camera_frames) if wants_media else None
    trajectories = []
    try:
        brain.warm_up()
        starts = spec.start_points(env.circuit.length)
        for i, start in enumerate(starts):
            what = f"{brain.name} on {spec.circuit} {spec.direction}, run {i + 1}/{len(starts)} from {start:.0f} m"
            report = None if progress is None else (lambda done, total, what=what: progress(done, total, what))
            trajectories.append(drive(env, brain, spec.drive, start=start, seed=spec.seed + i,
                                      render=brain.needs_camera or (wants_media and i == 0),
                                      on_frame=recorder if i == 0 else None, progress=report))
    finally:
        env.close()
        media = recorder.close() if recorder else {}
    return trajectories, media, env.circuit


def evaluate_online(brain: Brain, spec: OnlineSpec, out: Path, progress: ProgressFn | None = None) -> dict[str, Any]:
    """Drive, measure, and write the files; returns the result (see the module docstring)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    trajectories, media, circuit = run_all(brain, spec, out, progress)
    runs = [run_metrics(t) for t in trajectories]
    means, spread = aggregate(runs)
    save_npz(trajectories, out / "trajectory.npz")
    save_csv(trajectories, out / "trajectory.csv")
    title = picture_title(brain.name, spec, means, len(trajectories))
    plot_trajectories(circuit, trajectories, out / "trajectory.png", title=title)
    return {**means, "spread": spread, "runs": [run_summary(t, m) for t, m in zip(trajectories, runs)],
            "repetitions": len(trajectories), "brain": brain.name, "circuit": spec.circuit,
            "direction": spec.direction, "circuit_length_m": round(circuit.length, 3), "laps": spec.laps,
            "timeout_s": trajectories[0].meta["timeout_s"], **_drive_settings(spec.drive),
            "measured_inference_ms": float(np.mean([t.meta["measured_inference_ms"] for t in trajectories])),
            "trajectory": "trajectory.png", "trajectory_data": "trajectory.npz", "trajectory_csv": "trajectory.csv",
            **media, "wall_seconds": round(time.perf_counter() - started, 3)}


def run_summary(trajectory: Trajectory, metrics: dict[str, Any]) -> dict[str, Any]:
    meta = trajectory.meta
    return {"start_m": round(meta["start_m"], 3), "termination": meta["termination"],
            "sim_seconds": round(meta["sim_seconds"], 3), "wall_seconds": round(meta["wall_seconds"], 3),
            "iterations": len(trajectory.decisions), **{k: v for k, v in metrics.items() if v is not None}}


def _drive_settings(settings: DriveSettings) -> dict[str, Any]:
    values = asdict(settings)
    values.pop("version")
    return {k: v for k, v in values.items() if v is not None}


def picture_title(name: str, spec: OnlineSpec, means: dict[str, Any], runs: int) -> str:
    settings = spec.drive
    first = f"{name} on {spec.circuit} ({spec.direction}), {settings.timing} timing at {settings.control_hz:g} Hz"
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
