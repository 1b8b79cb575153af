"""`pilotlab record`: let the expert drive a circuit and save everything to a rosbag."""
from __future__ import annotations

import argparse
import re
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pydantic

from pilotlab.cli._options import add_spec_options, in_flags, spec_from_args
from pilotlab.cli._world import add_world_options, place_of
from pilotlab.errors import PilotlabError
from pilotlab.specs.base import CameraSize, spec_problem
from pilotlab.specs.record import RecordSpec


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "record", help="record a driving dataset (rosbag) with the expert driver",
        description="The expert drives the circuit in the pybullet simulator; camera frames, commands and odometry "
                    "go to a rosbag stamped in simulated time. Raw 640x480 frames at 10 Hz take about 9 MB per "
                    "simulated second (a lap of simple_circuit: ~430 MB); --compressed png keeps them lossless "
                    "in ~1% of that. Ctrl-C stops early and leaves a valid bag.")
    place = parser.add_mutually_exclusive_group(required=True)
    # not the spec's description, which speaks of planned jobs (and is in the record job's code: its key)
    place.add_argument("--circuit", help="circuit name (pilotlab circuit list) or CSV path")
    add_world_options(parser, place)
    parser.add_argument("--out", type=Path, required=True,
                        help="bag to write: a folder (ros2, the default format) or a file ending in .bag "
                             "(then ros1 unless --format says otherwise)")
    parser.add_argument("--size", help="camera frame WIDTHxHEIGHT (default 640x480)")
    add_spec_options(parser, RecordSpec, ["direction", "laps", "format", "seed", "rate_hz", "compressed", "noise",
                                          "renderer", "start", "max_seconds"], flags={"rate_hz": ["--rate"]})
    parser.set_defaults(func=run)


def parse_size(text: str) -> tuple[int, int]:
    match = re.fullmatch(r"(\d+)[xX×](\d+)", text.strip())
    if not match:
        raise PilotlabError(f"--size must be WIDTHxHEIGHT, e.g. 640x480; got {text!r}")
    return int(match.group(1)), int(match.group(2))


def camera_of(args: argparse.Namespace) -> dict:
    """{"camera": ...} for --size, else nothing (the spec's default camera)."""
    if args.size is None:
        return {}
    width, height = parse_size(args.size)
    try:
        return {"camera": CameraSize(width=width, height=height)}
    except pydantic.ValidationError as error:
        raise PilotlabError(f"--size {args.size}: {spec_problem(error).removeprefix('CameraSize: ')}") from None


def check_out(path: Path, format: str) -> None:
    """Before the progress bar: a bag that is there already, a file where its folder goes, or a ROS2
    bag's folder named as a ROS1 file."""
    from pilotlab.data.bagwrite import check_new_bag, storage_for
    try:
        check_new_bag(path)
        storage_for(path, "ros1" if format == "ros1" else "sqlite3")
    except PilotlabError as error:
        raise PilotlabError(f"--out: {error}") from None


def run(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from pilotlab.circuits.lookup import load_named
    from pilotlab.sim.env import describe_end
    from pilotlab.sim.record import record
    from pilotlab.sim.record import bag_path, check_rates
    place, assets, world = place_of(args)
    spec = spec_from_args(RecordSpec, args, **place, **camera_of(args),
                          **({"format": "ros1"} if args.out.suffix == ".bag" and not hasattr(args, "format") else {}))
    try:
        check_rates(spec)   # before the progress bar: an error is then the only line printed
    except PilotlabError as error:   # in the flags' words (it said rate_hz of --rate: outside test)
        raise PilotlabError(in_flags(str(error), RecordSpec, args)) from None
    check_out(bag_path(args.out, spec.format), spec.format)
    columns = (TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.completed:.0f}/{task.total:.0f} m"),
               TextColumn("{task.fields[frames]} frames"), TimeElapsedColumn(), TimeRemainingColumn())
    circuit = world.circuit(spec.direction) if world is not None else load_named(spec.circuit, spec.direction)
    with Progress(*columns) as progress, sigterm_as_ctrl_c() as terminated:
        task = progress.add_task(f"recording {spec.world or spec.circuit} {spec.direction}",
                                 total=circuit.length * spec.laps, frames=0)
        summary = record(spec, args.out, lambda done, total, frames: progress.update(
            task, completed=done, total=total, frames=frames), assets=assets)
    print(f"{summary.path}: {summary.frames} frames, {summary.commands} commands, {summary.sim_seconds:.1f} s "
          f"simulated in {summary.wall_seconds:.1f} s, {summary.distance_m:.0f} m at {summary.average_speed:.1f} m/s, "
          f"{summary.bytes / 2**20:.1f} MB ({describe_end(summary.termination, spec.laps)})")
    if summary.interrupted:
        print(f"{'terminated (SIGTERM)' if terminated.is_set() else 'interrupted'}: the bag holds what was recorded "
              "so far and is complete and readable")
        return 143 if terminated.is_set() else 130
    return 0


@contextmanager
def sigterm_as_ctrl_c() -> Iterator[threading.Event]:
    """SIGTERM (`kill PID`, `timeout`, a batch system) stops the recording as Ctrl-C does, the bag closed and
    readable (it killed the process: a ROS1 bag without its index, a ROS2 one without metadata.yaml: outside
    test). The event says whether it came."""
    terminated = threading.Event()

    def stop(signum, frame):
        terminated.set()
        signal.raise_signal(signal.SIGINT)     # the recorder's own polite stop (pilotlab.sim.record)
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield terminated
    finally:
        signal.signal(signal.SIGTERM, previous)
