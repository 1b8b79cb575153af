"""Recording a driving dataset: the expert drives a circuit and every message goes into a rosbag.

At each control step (20 Hz by default) the expert's command and the odometry are written; a camera
frame is rendered and written every `control_hz / rate_hz` steps. A frame and the command stamped
with the same time belong together: the command is what the expert decided on seeing that state.
With noise, the expert swerves now and then (see `pilotlab.sim.expert.Swerves`); the command written
is always the expert's clean one, so the swerves teach recoveries.

Sizes: a raw 640×480 rgb8 frame is 0.92 MB, so at the default 10 Hz a lap of simple_circuit (about
47 s) is about 430 MB; `compressed="jpeg"` makes that about 20 MB. Ctrl-C stops the recording after
the current step and closes the bag properly: what was recorded stays readable.
"""
from __future__ import annotations

import contextlib
import signal
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

import pilotlab
from pilotlab.errors import PilotlabError
from pilotlab.data.bagwrite import BagWriter, bag_path, to_nanoseconds
from pilotlab.sim.camera import CameraSpec
from pilotlab.sim.env import DrivingEnv
from pilotlab.sim.expert import BM_EXPERT, Expert, ExpertConfig, Swerves
from pilotlab.sim.world import PHYSICS_HZ
from pilotlab.specs.record import RecordSpec


def check_rates(spec: RecordSpec) -> None:
    """The control rate divides the physics rate, and the frame rate the control rate."""
    steps = PHYSICS_HZ / spec.control_hz
    if abs(steps - round(steps)) > 1e-9:
        raise PilotlabError(f"control_hz must divide the physics rate {PHYSICS_HZ:g} Hz (e.g. 20, 10); "
                            f"got {spec.control_hz}")
    every = spec.control_hz / spec.rate_hz
    if not (every >= 1 and abs(every - round(every)) < 1e-9):
        divisors = [f"{spec.control_hz / k:g}" for k in range(1, 11) if (spec.control_hz / k) % 1 == 0]
        raise PilotlabError(f"rate_hz must divide the control rate {spec.control_hz:g} Hz "
                            f"({', '.join(divisors)}...); got {spec.rate_hz}")


@dataclass
class RecordSummary:
    path: str
    format: str
    frames: int
    commands: int
    odometry: int
    sim_seconds: float
    wall_seconds: float
    distance_m: float
    laps_completed: int
    termination: str | None
    interrupted: bool
    bytes: int
    mean_distance_to_line_m: float
    max_distance_to_line_m: float
    average_speed: float

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


ProgressFn = Callable[[float, float, int], None]  # (metres driven, metres to drive, frames written)


@contextlib.contextmanager
def stop_on_interrupt():
    """Turn Ctrl-C into a polite request (`flag["stop"]`), so the bag is closed properly."""
    flag = {"stop": False}

    def request_stop(signum, frame):
        flag["stop"] = True
    try:
        previous = signal.signal(signal.SIGINT, request_stop)
    except ValueError:  # not the main thread: nobody can press Ctrl-C at us here
        yield flag
        return
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, previous)


def record(spec: RecordSpec, out: Path, progress: ProgressFn | None = None, assets=None) -> RecordSummary:
    """Drive `spec.laps` laps with the expert and write them to a bag at `out` (a `.bag` file for
    ROS1, a folder for ROS2). Returns what was written. In a BM world (`spec.world`), `assets` is the
    folder of BM's worlds (default $PILOTLAB_BM_ASSETS)."""
    check_rates(spec)
    path = bag_path(out, spec.format)
    camera = CameraSpec(width=spec.camera.width, height=spec.camera.height)
    place = {"world": spec.world, "assets": assets} if spec.world else {"circuit": spec.circuit}
    env = DrivingEnv(**place, direction=spec.direction, camera=camera, renderer=spec.renderer,
                     control_period=1.0 / spec.control_hz, laps=spec.laps, timeout_s=spec.max_seconds)
    started = time.perf_counter()
    try:
        storage = "ros1" if spec.format == "ros1" else "sqlite3"
        with BagWriter(path, storage=storage, compression=spec.compressed) as bag, stop_on_interrupt() as interrupt:
            stats = _drive(env, spec, bag, interrupt, progress)
    finally:
        env.close()
    return RecordSummary(path=str(path), format=spec.format, frames=bag.counts[bag.image_topic],
                         commands=stats["commands"], odometry=stats["commands"], sim_seconds=stats["sim_time"],
                         wall_seconds=time.perf_counter() - started, distance_m=stats["progress"],
                         laps_completed=stats["laps_completed"], termination=stats["termination"],
                         interrupted=interrupt["stop"], bytes=size_on_disk(path),
                         mean_distance_to_line_m=stats["mean_distance"], max_distance_to_line_m=stats["max_distance"],
                         average_speed=stats["progress"] / max(stats["sim_time"], 1e-9))


def _drive(env: DrivingEnv, spec: RecordSpec, bag: BagWriter, interrupt: dict, progress: ProgressFn | None) -> dict:
    obs, info = env.reset(seed=spec.seed, options={"start": spec.start})
    bag.metadata(metadata(spec, env))
    expert = Expert(env.circuit, ExpertConfig(**BM_EXPERT) if env.bm is not None else ExpertConfig())
    swerves = Swerves(spec.noise, np.random.default_rng([spec.seed, 1]), expert)
    frame_every = round(spec.control_hz / spec.rate_hz)
    total = spec.laps * env.circuit.length
    distances, steps = [], 0
    while True:
        stamp = to_nanoseconds(info["sim_time"])
        command = expert.act(info)
        if steps % frame_every == 0:
            bag.image(stamp, obs if obs is not None else env.render())
        bag.command(stamp, *command)
        bag.odometry(stamp, info["position"], info["orientation"], info["speed"], info["yaw_rate"])
        distances.append(info["distance_to_line"])
        obs, _, terminated, truncated, info = env.step(swerves(command, info, env.control_period), render=False)
        steps += 1
        done = terminated or truncated or interrupt["stop"]
        if progress is not None and (steps % 10 == 0 or done):
            progress(max(info["progress"], 0.0), total, bag.counts[bag.image_topic])
        if done:
            break
    return {"commands": steps, "sim_time": info["sim_time"], "progress": info["progress"],
            "laps_completed": info["laps_completed"], "termination": info["termination"],
            "mean_distance": float(np.mean(distances)), "max_distance": float(np.max(distances))}


def metadata(spec: RecordSpec, env: DrivingEnv) -> dict[str, Any]:
    circuit = env.circuit
    return {"pilotlab_version": pilotlab.__version__, "circuit": circuit.name, "direction": circuit.direction,
            "circuit_length_m": round(circuit.length, 3), "circuit_source": circuit.source,
            "road_width_m": circuit.road_width, "seed": spec.seed, "laps": spec.laps, "noise": spec.noise,
            "camera": {**spec.camera.as_dict(), "hfov_deg": env.camera.hfov_deg},
            "rate_hz": spec.rate_hz, "control_hz": spec.control_hz, "renderer": spec.renderer,
            "compressed": spec.compressed, "start": spec.start, "driver": "expert",
            **({"world": spec.world, "world_digest": env.bm.digest,
                "camera_mount_m": [env.camera.forward_m, env.camera.lateral_m, env.camera.height_m]}
               if env.bm is not None else {})}


def size_on_disk(path: Path) -> int:
    path = Path(path)
    if path.is_dir():
        return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    return path.stat().st_size if path.exists() else 0
