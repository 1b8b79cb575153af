"""`pilotlab drive`: a closed-loop evaluation outside a recipe, the online job's work by hand.

    pilotlab drive --artifact .pilotlab/<key>/artifacts --circuit simple_circuit --out runs/baseline
    pilotlab drive --brain explicit --circuit montreal --direction ccw --repetitions 3 --out runs/explicit
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
from pathlib import Path

from pilotlab.errors import PilotlabError


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "drive", help="drive a circuit with an optimized artifact or a reference brain; BehaviorMetrics' metrics",
        description="Runs a brain in closed loop in the pybullet simulator and writes trajectory.png, "
                    "trajectory.npz/.csv, result.json (and camera.mp4 with --video) into --out. Give an "
                    "artifact folder (what an optimize job wrote, or `pilotlab export` copied) or --brain.")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--artifact", type=Path, help="artifact folder (artifact.json + model file)")
    which.add_argument("--brain", choices=("explicit", "expert"), help="a reference brain")
    parser.add_argument("--circuit", required=True, help="circuit name (pilotlab circuit list) or CSV path")
    parser.add_argument("--direction", choices=("cw", "ccw"), default="cw")
    parser.add_argument("--out", type=Path, required=True, help="folder for the pictures, data and result.json")
    parser.add_argument("--hardware", default="cpu", help="hardware profile: cpu, cpu1 or cuda (default cpu)")
    parser.add_argument("--timing", choices=("latency", "lockstep", "realtime"), default="latency",
                        help="latency (default): each measured inference time passes in simulated time with the "
                             "previous command in force; lockstep: the world waits for the brain; realtime: "
                             "simulated time follows the wall clock")
    parser.add_argument("--control-hz", type=float, default=20.0, help="brain iterations per second (default 20)")
    parser.add_argument("--extra-latency-ms", type=float, default=0.0, help="artificial latency per iteration")
    parser.add_argument("--repetitions", type=int, default=1, help="runs, from start points spread round the lap")
    parser.add_argument("--laps", type=float, default=1.0)
    parser.add_argument("--timeout", type=float, default=None, help="simulated seconds (default: the circuit's)")
    parser.add_argument("--video", action="store_true", help="write camera.mp4 of the first run's first 20 s")
    parser.set_defaults(func=run)


def params_of(args: argparse.Namespace) -> dict:
    """The online job's params for these arguments."""
    return {"circuit": args.circuit, "direction": args.direction, "timing": args.timing,
            "control_hz": args.control_hz, "extra_latency_ms": args.extra_latency_ms,
            "repetitions": args.repetitions, "laps": args.laps, "timeout_s": args.timeout, "video": args.video}


def check_arguments(args: argparse.Namespace) -> None:
    """What can be told wrong before the simulator starts."""
    if args.artifact is not None and not args.artifact.is_dir():
        raise PilotlabError(f"--artifact {args.artifact}: no such folder")
    if args.out.exists() and (not args.out.is_dir() or any(args.out.iterdir())):
        what = "is a file" if not args.out.is_dir() else "is a folder that is not empty"
        raise PilotlabError(f"--out {args.out} {what}; give a new folder (drive does not mix two runs' files)")
    for option, value, least in (("--laps", args.laps, 0.0), ("--repetitions", args.repetitions, 0),
                                 ("--control-hz", args.control_hz, 0.0)):
        if value is not None and not value > least:   # also true for NaN
            raise PilotlabError(f"{option} {value:g}: must be above {least:g}")
    for option, value in (("--laps", args.laps), ("--control-hz", args.control_hz), ("--timeout", args.timeout),
                          ("--extra-latency-ms", args.extra_latency_ms)):
        if value is not None and not math.isfinite(value):
            raise PilotlabError(f"{option} {value:g}: must be a finite number")
    if args.timeout is not None and args.timeout <= 0:
        raise PilotlabError(f"--timeout {args.timeout:g}: must be above 0 simulated seconds")
    if args.extra_latency_ms < 0:
        raise PilotlabError(f"--extra-latency-ms {args.extra_latency_ms:g}: must be 0 or more")
    from pilotlab.circuits import get_circuit
    get_circuit(args.circuit, args.direction)   # an unknown or broken circuit, before the progress bar


def run(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from pilotlab.hardware import check_available, make_profile
    from pilotlab.jobs.online import DEFAULTS, online_spec
    from pilotlab.online.brains import NetworkBrain, make_reference_brain
    from pilotlab.online.evaluate import evaluate_online
    from pilotlab.predictor import load_predictor
    from pilotlab.report import pick_metrics

    check_arguments(args)
    profile = make_profile(args.hardware)
    check_available(profile)
    brain = (NetworkBrain(load_predictor(args.artifact, profile)) if args.artifact is not None
             else make_reference_brain(args.brain))
    spec = online_spec({**DEFAULTS, **params_of(args)})
    columns = (TextColumn("[bold]{task.description}"), BarColumn(),
               TextColumn("{task.completed:.0f}/{task.total:.0f} m"), TimeElapsedColumn())
    created = not args.out.exists()
    try:
        with Progress(*columns) as progress:
            task = progress.add_task("starting", total=1.0)
            result = evaluate_online(brain, spec, args.out, lambda done, total, what: progress.update(
                task, completed=done, total=total, description=what))
    except BaseException:
        if created:   # a failed or interrupted drive leaves no half-written --out behind
            shutil.rmtree(args.out, ignore_errors=True)
        raise
    result = {**result, "hardware": profile.as_dict()}
    (args.out / "result.json").write_text(json.dumps(result, indent=1))
    console = Console()
    for name, value in pick_metrics(result).items():
        console.print(f"  {name:28s} {value:.4g}" if isinstance(value, float) else f"  {name:28s} {value}")
    console.print(f"wrote {args.out / result['trajectory']} and {args.out / 'result.json'}")
    return 0
