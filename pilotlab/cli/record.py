"""`pilotlab record`: let the expert drive a circuit and save everything to a rosbag."""
from __future__ import annotations

import argparse
import math
import re
from pathlib import Path

from pilotlab.errors import PilotlabError


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "record", help="record a driving dataset (rosbag) with the expert driver",
        description="The expert drives the circuit in the pybullet simulator; camera frames, commands and odometry "
                    "go to a rosbag stamped in simulated time. Raw 640x480 frames at 10 Hz take about 9 MB per "
                    "simulated second (a lap of simple_circuit: ~430 MB); --compressed png keeps them lossless "
                    "in ~1% of that. Ctrl-C stops early and leaves a valid bag.")
    parser.add_argument("--circuit", required=True, help="circuit name (pilotlab circuit list) or CSV path")
    parser.add_argument("--direction", choices=("cw", "ccw"), default="cw")
    parser.add_argument("--laps", type=float, default=1.0, help="laps to drive (fractions allowed)")
    parser.add_argument("--out", type=Path, required=True,
                        help="bag to write: a .bag file (ros1; .bag is added if missing) or a folder (ros2)")
    parser.add_argument("--format", choices=("ros1", "ros2"), default="ros1")
    parser.add_argument("--seed", type=int, default=0, help="seeds the noise and a random start")
    parser.add_argument("--size", default="640x480", help="camera frame WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--rate", type=float, default=10.0, help="camera frames per simulated second (default 10)")
    parser.add_argument("--compressed", choices=("jpeg", "png"), default=None,
                        help="write sensor_msgs/CompressedImage instead of raw rgb8 Image")
    parser.add_argument("--noise", type=float, default=0.0,
                        help="fraction of time the expert swerves and recovers (0 = never, e.g. 0.1)")
    parser.add_argument("--renderer", choices=("ground", "pybullet"), default="ground",
                        help="ground: fast ground-plane renderer (default); pybullet: TinyRenderer reference")
    parser.add_argument("--start", default="0", help="start point, metres along the lap, or 'random'")
    parser.add_argument("--max-seconds", type=float, default=None, help="stop after this much simulated time")
    parser.set_defaults(func=run)


def parse_size(text: str) -> tuple[int, int]:
    match = re.fullmatch(r"(\d+)[xX×](\d+)", text.strip())
    if not match:
        raise PilotlabError(f"--size must be WIDTHxHEIGHT, e.g. 640x480; got {text!r}")
    return int(match.group(1)), int(match.group(2))


def parse_start(text: str) -> float | str:
    try:
        start = text if text == "random" else float(text)
    except ValueError:
        start = math.nan
    if start != "random" and not math.isfinite(start):
        raise PilotlabError(f"--start must be metres along the lap or 'random'; got {text[:40]!r}")
    return start


def check_numbers(args: argparse.Namespace) -> None:
    """Numbers that would make a recording never end (NaN laps) or never start, refused before it starts."""
    for option, value in (("--laps", args.laps), ("--rate", args.rate), ("--max-seconds", args.max_seconds)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise PilotlabError(f"{option} must be a positive number; got {value}")
    if not 0 <= args.noise <= 1:   # also false for NaN
        raise PilotlabError(f"--noise must be a fraction in [0, 1]; got {args.noise}")


def run(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from pilotlab.circuits import get_circuit
    from pilotlab.sim.record import RecordSpec, record
    check_numbers(args)
    width, height = parse_size(args.size)
    start = parse_start(args.start)
    spec = RecordSpec(circuit=args.circuit, direction=args.direction, laps=args.laps, seed=args.seed, width=width,
                      height=height, rate_hz=args.rate, format=args.format, compressed=args.compressed,
                      noise=args.noise, renderer=args.renderer, start=start, max_seconds=args.max_seconds)
    spec.check()   # before the progress bar: an error is then the only line printed
    columns = (TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.completed:.0f}/{task.total:.0f} m"),
               TextColumn("{task.fields[frames]} frames"), TimeElapsedColumn(), TimeRemainingColumn())
    total = get_circuit(args.circuit).length * args.laps
    with Progress(*columns) as progress:
        task = progress.add_task(f"recording {args.circuit} {args.direction}", total=total, frames=0)
        summary = record(spec, args.out, lambda done, total, frames: progress.update(
            task, completed=done, total=total, frames=frames))
    print(f"{summary.path}: {summary.frames} frames, {summary.commands} commands, {summary.sim_seconds:.1f} s "
          f"simulated in {summary.wall_seconds:.1f} s, {summary.distance_m:.0f} m at {summary.average_speed:.1f} m/s, "
          f"{summary.bytes / 1e6:.1f} MB ({summary.termination or 'stopped'})")
    if summary.interrupted:
        print("interrupted: the bag holds what was recorded so far and is complete and readable")
        return 130
    return 0
