"""The `record` job: the expert drives a circuit in the simulator and the run is saved as a rosbag.

Its settings are shared by the recipe (`datasets.<name>.record`, which adds lists of circuits and
directions) and by `pilotlab record` (whose options are built from these fields).
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from matrix.kinds import register_kind
from pilotlab.specs.base import CONTROL_HZ, CameraSize, Direction, InWorld, Spec

BAG_FORMATS = ("ros1", "ros2")


class RecordSettings(Spec):
    laps: float = Field(1.0, gt=0, le=1000, description="laps to drive (fractions allowed)")
    seed: int = Field(0, ge=0, lt=2**32, description="seeds the noise and a random start; same seed, same bag")
    rate_hz: float = Field(10.0, gt=0, description="camera frames per simulated second (must divide control_hz)")
    control_hz: float = Field(CONTROL_HZ, gt=0, description="commands and odometry per simulated second")
    camera: CameraSize = CameraSize()
    noise: float = Field(0.0, ge=0, le=1, description="fraction of time the expert swerves and recovers (0.1 is "
                                                       "a good dose)")
    compressed: Literal["jpeg", "png"] | None = Field(
        None, description="write sensor_msgs/CompressedImage (jpeg or png) instead of raw rgb8 Image")
    # ROS2 is today's ROS, and a folder bag carries pilotlab's metadata in metadata.yaml too; pass
    # "ros1" for a single .bag file (BehaviorMetrics' and DeepLearningStudio's noetic tools read it).
    format: Literal["ros1", "ros2"] = Field("ros2", description="ros2 (a bag folder) or ros1 (a .bag file)")
    renderer: Literal["ground", "pybullet"] = Field(
        "ground", description="ground: fast ground-plane renderer; pybullet: TinyRenderer reference (slow)")

    @field_validator("compressed", mode="before")
    @classmethod
    def _compressed_true_is_jpeg(cls, value):
        """`compressed: true` in a recipe means JPEG; false means raw frames."""
        return "jpeg" if value is True else (None if value is False else value)


class RecordSpec(RecordSettings, InWorld):
    """One recording: the settings, plus where and from where to drive (in a BM world, `circuit` is
    the world's own)."""
    circuit: str = Field(min_length=1, description="circuit name (pilotlab circuit list) or CSV path; a planned "
                                                     "job's CSV is its `circuit_csv` input (see with_circuit_file)")
    direction: Direction = "cw"
    start: float | Literal["random"] = Field(0.0, description="start point, metres along the lap, or 'random'")
    max_seconds: float | None = Field(None, gt=0, description="stop after this much simulated time "
                                                              "(default: the circuit's timeout × laps)")
    version: int = 1


register_kind("record", "pilotlab.jobs.record:run_record", params=RecordSpec)


def with_circuit_file(spec, inputs):
    """A planned job's spec (record or online) driving its `circuit_csv` input where it has one: the
    param names a user's CSV only by its stem, so the job's key follows the file's content, not its place."""
    csv = inputs.get("circuit_csv")
    return spec if csv is None else spec.model_copy(update={"circuit": str(csv)})
