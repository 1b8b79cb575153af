"""`pilotlab drive`: a closed-loop evaluation outside a recipe, the online job's work by hand.

    pilotlab drive --artifact .pilotlab/<key>/artifacts --circuit simple_circuit --out runs/baseline
    pilotlab drive --brain explicit --circuit montreal --direction ccw --repetitions 3 --out runs/explicit
    pilotlab drive --brain brains/mine.py:MyBrain --circuit simple_circuit --out runs/mine   (docs/brains.md)
"""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path
from typing import Any

from pilotlab.cli._options import add_spec_options, spec_from_args
from pilotlab.cli._world import add_world_options, place_of
from pilotlab.errors import PilotlabError
from pilotlab.specs.online import OnlineSpec

LAP_OPTIONS = ["direction", "timing", "control_hz", "extra_latency_ms", "fixed_inference_ms", "repetitions", "laps",
               "seed", "timeout_s", "stop_off_road", "trapped_s", "renderer", "video", "video_seconds",
               "camera_frames", "latency_scale_to_ms"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "drive", help="drive a circuit with an optimized artifact or a reference brain; BehaviorMetrics' metrics",
        description="Runs a brain in closed loop in the pybullet simulator and writes trajectory.png, "
                    "trajectory.npz/.csv, result.json (and camera.mp4 with --video) into --out. Give an "
                    "artifact folder (what an optimize job wrote, or `pilotlab export` copied) or --brain.")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--artifact", type=Path, help="artifact folder (artifact.json + model file)")
    which.add_argument("--brain", metavar="BRAIN",
                       help="a reference brain (explicit, expert) or yours: file.py:Class or module:Class, a class "
                            "with act(image) -> (v, w) (docs/brains.md)")
    place = parser.add_mutually_exclusive_group(required=True)
    place.add_argument("--circuit", help="circuit name (pilotlab circuit list) or CSV path")
    add_world_options(parser, place)
    parser.add_argument("--out", type=Path, required=True, help="folder for the pictures, data and result.json")
    parser.add_argument("--hardware", default="cpu", help="hardware profile: cpu, cpu1 or cuda (default cpu)")
    add_spec_options(parser, OnlineSpec, LAP_OPTIONS, flags={"timeout_s": ["--timeout"]})
    parser.add_argument("--latency-file", type=Path, default=None,
                        help="replay a device's measured latencies: a CSV with a latency_ms column (optionally "
                             "model, strategy; docs/simulator.md); without it an artifact's predict call is timed "
                             "here once before the lap and replayed")
    parser.add_argument("--tolerance", action="store_true",
                        help="also search the largest injected latency at which the lap is still completed "
                             "(on top of --extra-latency-ms, which every lap of the search carries)")
    parser.set_defaults(func=run)


def replayed_samples(args: argparse.Namespace, spec: OnlineSpec, brain) -> tuple[Any, dict]:
    """The latencies the replay mode draws from, and what the result says of them: the --latency-file's
    rows for this brain (model: an artifact's arch, strategy: its strategy or the reference brain's
    name), else the network's predict call timed here once before the lap; nothing for a reference brain."""
    import numpy as np

    from pilotlab.online.latency import describe, latency_file_samples, measure_samples
    if spec.timing != "replay" or spec.fixed_inference_ms is not None:
        return None, {}
    if args.latency_file is not None:
        predictor = getattr(brain, "predictor", None)
        samples = latency_file_samples(args.latency_file, predictor.meta.arch if predictor else None, brain.name)
        return samples, describe(samples, f"latency file {args.latency_file.name}")
    if args.artifact is not None:
        samples = measure_samples(brain)
        return samples, describe(samples, "predict timed here before the lap")
    from pilotlab.jobs.online import CHARGED_NOTHING
    return np.zeros(1), describe(np.zeros(1), CHARGED_NOTHING)


def check_arguments(args: argparse.Namespace) -> None:
    """What can be told wrong before the simulator starts (the lap settings: by the spec)."""
    if args.artifact is not None and not args.artifact.is_dir():
        what = (f"a file; give the artifact's folder ({args.artifact.parent}, which holds artifact.json)"
                if args.artifact.is_file() else "no such folder")
        raise PilotlabError(f"--artifact {args.artifact}: {what}")
    if args.latency_file is not None and not args.latency_file.is_file():
        raise PilotlabError(f"--latency-file {args.latency_file}: no such file")
    if args.out.exists() and (not args.out.is_dir() or any(args.out.iterdir())):
        what = "is a file" if not args.out.is_dir() else "is a folder that is not empty"
        raise PilotlabError(f"--out {args.out} {what}; give a new folder (drive does not mix two runs' files)")


def brain_params(brain: str | None, world=None) -> dict:
    """The online job's brain params for --brain: a reference brain's name, or the user's
    `file.py:Class` (relative to the current folder), its row named after the class. In a BM `world`
    the explicit brain gets the options for BM's camera and the world's line colour."""
    from matrix.errors import did_you_mean
    from pilotlab.online.brains import REFERENCE_BRAINS
    if brain is None:
        return {"brain": "network"}
    if ":" in brain:
        return {"brain": "user", "user_brain": {"name": brain.rpartition(":")[2], "spec": brain,
                                                "base": str(Path.cwd())}}
    if brain.endswith(".py") or "/" in brain:   # a file without its class said "unknown brain" (outside test)
        raise PilotlabError(f"--brain {brain}: name the class in it too, as {brain}:ClassName (a class with "
                            "act(image) returning (v, w): docs/brains.md)")
    if brain not in REFERENCE_BRAINS:
        known = REFERENCE_BRAINS.names()
        raise PilotlabError(f"--brain {brain}: unknown brain{did_you_mean(brain, known)}; give {', '.join(known)}, "
                            "or your own as file.py:Class or module:Class")
    if brain == "explicit" and world is not None:
        from pilotlab.sim.explicit import bm_world_options
        return {"brain": brain, "brain_options": bm_world_options(world.line_colour)}
    if brain == "expert" and world is not None:
        from pilotlab.sim.expert import BM_EXPERT
        return {"brain": brain, "brain_options": dict(BM_EXPERT)}
    return {"brain": brain}


def make_brain(spec: OnlineSpec):
    from pilotlab.online.brains import UserBrain, make_reference_brain
    if spec.user_brain is not None:
        mine = spec.user_brain
        return UserBrain(mine.spec, Path(mine.base), name=mine.name)
    return make_reference_brain(spec.brain, spec.brain_options)


def run(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from pilotlab.hardware import check_available, make_profile
    from pilotlab.online.brains import NetworkBrain
    from pilotlab.online.evaluate import evaluate_online
    from pilotlab.predictor import load_predictor
    from pilotlab.report import pick_metrics

    from pilotlab.circuits.lookup import load_named
    from pilotlab.jobs.online import CHARGED_NOTHING, without_uncharged_inference
    check_arguments(args)
    place, assets, world = place_of(args)
    spec = spec_from_args(OnlineSpec, args, **place, **brain_params(args.brain, world), tolerance=args.tolerance)
    if world is None:
        load_named(spec.circuit, spec.direction)   # an unknown or broken circuit: before the progress bar
    profile = make_profile(args.hardware)
    check_available(profile)
    brain = (NetworkBrain(load_predictor(args.artifact, profile)) if args.artifact is not None
             else make_brain(spec))
    samples, replayed = replayed_samples(args, spec, brain)
    columns = (TextColumn("[bold]{task.description}"), BarColumn(),
               TextColumn("{task.completed:.0f}/{task.total:.0f} m"), TimeElapsedColumn())
    created = not args.out.exists()
    try:
        with Progress(*columns, transient=True) as progress:   # its last line named the last lap driven
            task = progress.add_task("starting", total=1.0)
            result = evaluate_online(brain, spec, args.out, lambda done, total, what: progress.update(
                task, completed=done, total=total, description=what), latency_ms=samples,
                tolerance=spec.tolerance, assets=assets)
    except BaseException:
        if created:   # a failed or interrupted drive leaves no half-written --out behind
            shutil.rmtree(args.out, ignore_errors=True)
        raise
    result = {**result, **replayed, "hardware": profile.as_dict()}
    if replayed.get("latency_source") == CHARGED_NOTHING:   # as the online job: no inference time to report
        result = without_uncharged_inference(result)
    (args.out / "result.json").write_text(json.dumps(result, indent=1))
    console = Console()
    for name, value in pick_metrics(result).items():
        if value is None or name == "latency_tolerance_ms":   # None: not measured (a reference brain's inference
            continue                                           # time), said nowhere, as in the report
        console.print(f"  {name:28s} {value:.4g}" if isinstance(value, float) else f"  {name:28s} {value}")
    console.print(f"  {'termination':28s} " + "; ".join(f"{run['termination']} after {run['sim_seconds']:.1f} s"
                                                      for run in result.get("runs", [])))
    if spec.tolerance is not None:
        console.print(f"  {'latency_tolerance_ms':28s} {tolerance_said(result, spec.tolerance.max_ms)}")
    if spec.extra_latency_ms and result.get("latency_tolerance_ms") is not None:
        console.print(f"  (the latency tolerance is on top of --extra-latency-ms {spec.extra_latency_ms:g}: the lap is "
                      f"still completed with {spec.extra_latency_ms + result['latency_tolerance_ms']:g} ms injected in all)")
    console.print(f"wrote {args.out / result['trajectory']} and {args.out / 'result.json'}")
    return 0


def tolerance_said(result: dict, max_ms: float) -> str:
    """The search's answer in words: the tolerance, "≥" it when never lost, or that the lap was lost with
    nothing injected (the result's latency_tolerance_ms is then null)."""
    found = result.get("latency_tolerance_ms")
    if found is None:
        return "none: the lap is lost with nothing injected"
    if result.get("tolerance_at_least"):
        return f"≥ {found:g} (still completed at the search's largest, max_ms {max_ms:g})"
    return f"{found:g}"
