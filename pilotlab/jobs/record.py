"""The `record` job kind: the expert drives a circuit in the simulator and the run is saved as a rosbag.

Params (all JSON; only `circuit` is required):
    circuit      str    circuit name (built-in, ./circuits/NAME.csv, $PILOTLAB_CIRCUITS) or a CSV path
    direction    str    "cw" (default) | "ccw"
    laps         float  laps to drive, fractions allowed (default 1)
    seed         int    seeds the noise and a random start (default 0); same seed, same bag
    width        int    camera frame width (default 640)
    height       int    camera frame height (default 480)
    rate_hz      float  camera frames per simulated second, must divide control_hz (default 10)
    control_hz   float  commands and odometry per simulated second (default 20)
    format       str    "ros1" (default; writes recording.bag) | "ros2" (writes the folder recording/)
    compressed   str|bool|null  null/false: raw rgb8 Image (default); "jpeg" (or true) | "png": CompressedImage
    noise        float  fraction of time the expert swerves and recovers (default 0; 0.1 is a good dose)
    renderer     str    "ground" (default, fast) | "pybullet" (TinyRenderer, the reference, slow at 640x480)
    start        float|str  metres along the lap to start at, or "random" (default 0)
    max_seconds  float|null stop after this much simulated time (default: the circuit's timeout × laps,
                            at least one lap's)

Result: the RecordSummary fields (frames, commands, odometry, sim_seconds, wall_seconds, distance_m,
laps_completed, termination, bytes, mean/max_distance_to_line_m, average_speed, ...), `bag` (and
`path`, the same): the bag relative to ctx.out ("recording.bag" or "recording"), plus `topics`
(role -> topic). A `frames` job that depends on it reads `artifacts / result["bag"]`.

A circuit given as a CSV is an input file: its content should be part of the job key
(`pilotlab.circuits.csv_path_of(name)` says which file, None for built-ins).
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from matrix.kinds import JobContext, job_kind
from pilotlab.errors import PilotlabError

if TYPE_CHECKING:  # the simulator (pybullet, OpenCV, rosbags): imported by the handler, not to plan
    from pilotlab.sim import record

CODE = ["pilotlab.sim.record", "pilotlab.sim.bagwriter", "pilotlab.sim.env", "pilotlab.sim.expert", "pilotlab.sim.car",
        "pilotlab.sim.camera", "pilotlab.sim.render", "pilotlab.sim.world", "pilotlab.circuits.circuit",
        "pilotlab.circuits.geometry", "pilotlab.circuits.registry"]


def record_spec(params) -> record.RecordSpec:
    """A RecordSpec from job params; unknown params are an error."""
    from pilotlab.sim import record
    known = {f.name for f in dataclasses.fields(record.RecordSpec)} - {"version"}
    unknown = sorted(set(params) - known)
    if unknown:
        raise PilotlabError(f"record job: unknown param(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    if "circuit" not in params:
        raise PilotlabError("record job: the param 'circuit' is required")
    values = dict(params)
    compressed = values.get("compressed")
    values["compressed"] = "jpeg" if compressed is True else (compressed or None)
    return record.RecordSpec(**values)


@job_kind("record", code=CODE)
def run_record(ctx: JobContext) -> dict:
    from pilotlab.sim import bagwriter, record
    spec = record_spec(ctx.params)
    name = "recording.bag" if spec.format == "ros1" else "recording"
    label = f"recording {spec.circuit} {spec.direction}"
    ctx.log.info("%s: %s", label, spec)
    summary = record.record(spec, ctx.out / name, lambda done, total, frames: ctx.progress(done, total, label))
    if summary.interrupted:
        raise PilotlabError(f"{label}: interrupted after {summary.frames} frames")
    result = summary.as_dict()
    result["bag"] = result["path"] = name
    result["topics"] = {"image": bagwriter.COMPRESSED_TOPIC if spec.compressed else bagwriter.IMAGE_TOPIC,
                        "cmd_vel": bagwriter.CMD_TOPIC, "odom": bagwriter.ODOM_TOPIC,
                        "metadata": bagwriter.METADATA_TOPIC}
    return result
