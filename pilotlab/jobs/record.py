"""The `record` job's handler (params: pilotlab.specs.record.RecordSpec).

Result: the RecordSummary fields (frames, commands, odometry, sim_seconds, wall_seconds, distance_m,
laps_completed, termination, bytes, mean/max_distance_to_line_m, average_speed, ...), `bag` (and
`path`, the same): the bag relative to ctx.out ("recording.bag" or "recording"), plus `topics`
(role -> topic). A `frames` job that depends on it reads `artifacts / result["bag"]`.
"""
from __future__ import annotations

from matrix.kinds import JobContext
from pilotlab.data import topics
from pilotlab.errors import PilotlabError
from pilotlab.sim import record
from pilotlab.specs.record import RecordSpec, with_circuit_file
from pilotlab.worlds.assets import world_assets


def run_record(ctx: JobContext) -> dict:
    spec: RecordSpec = with_circuit_file(ctx.spec, ctx.inputs)
    name = "recording.bag" if spec.format == "ros1" else "recording"
    assets, _ = world_assets(ctx.inputs)
    label = f"recording {spec.world or spec.circuit} {spec.direction}"
    ctx.log.info("%s: %s", label, spec)
    summary = record.record(spec, ctx.out / name, lambda done, total, frames: ctx.progress(done, total, label),
                            assets=assets)
    if summary.interrupted:
        raise PilotlabError(f"{label}: interrupted after {summary.frames} frames")
    result = summary.as_dict()
    result["bag"] = result["path"] = name
    result["topics"] = {"image": topics.COMPRESSED_IMAGE_TOPIC if spec.compressed else topics.IMAGE_TOPIC,
                        "cmd_vel": topics.COMMAND_TOPIC, "odom": topics.ODOMETRY_TOPIC,
                        "metadata": topics.METADATA_TOPIC}
    return result
