"""The domain's recipe sections (the engine validates `name`, `description` and `matrix`).

    datasets:    named datasets: recorded in the simulator, or the user's bags / DLS folders
    circuits:    extra circuits from CSV files of x,y points (the five JdeRobot ones are built in)
    models:      named networks with their training settings
    strategies:  options for strategies, or new names for a strategy with other options (`use:`)
    hardware:    named hardware profiles beside the built-in cpu, cpu1 and cuda
    offline:     offline evaluation settings
    online:      closed-loop evaluation settings
    report:      where reports go
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from matrix.errors import did_you_mean


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CameraSpec(Strict):
    width: int = Field(640, ge=16, le=4096)
    height: int = Field(480, ge=16, le=4096)


class RecordSpec(Strict):
    """Drive circuits with the expert in the simulator and record rosbags."""
    circuits: list[str] = Field(min_length=1)
    directions: list[Literal["cw", "ccw"]] = Field(["cw"], min_length=1)
    laps: float = Field(1.0, gt=0)
    seed: int = 0
    rate_hz: float = Field(10.0, gt=0, description="camera frames recorded per simulated second")
    camera: CameraSpec = CameraSpec()
    noise: float = Field(0.0, ge=0, le=1, description="how often the expert swerves and recovers")
    compressed: bool = False
    format: Literal["ros1", "ros2"] = "ros2"


class TopicsSpec(Strict):
    image: str | None = None
    command: str | None = None


class DatasetSpec(Strict):
    record: RecordSpec | None = None
    bags: list[str] = []          # ROS1 .bag files or ROS2 bag folders
    folders: list[str] = []       # DeepLearningStudio folders (<n>.png + data.csv)
    topics: TopicsSpec = TopicsSpec()

    @model_validator(mode="after")
    def _has_a_source(self):
        if self.record is None and not self.bags and not self.folders:
            raise ValueError("a dataset needs `record`, `bags` or `folders`")
        return self


class CircuitSpec(Strict):
    csv: str                      # x,y points of the centreline, in metres
    road_width: float | None = None
    closed: bool = True


class AugmentSpec(Strict):
    """Training-time augmentation (pilotlab.data.augment.AugmentConfig)."""
    flip: bool = False
    oversample_curves: float = Field(0.0, ge=0, description="extra weight of curve frames (0: none)")
    curve_threshold: float = Field(0.3, ge=0, le=1)
    color_jitter: float = Field(0.0, ge=0, le=1)
    blur: float = Field(0.0, ge=0, le=1)
    affine: float = Field(0.0, ge=0, le=1)


class ModelSpec(Strict):
    arch: str = "pilotnet"
    options: dict[str, Any] = {}  # fields of the arch's config (e.g. frames for pilotnet_stacked)
    data: str = "train"           # the dataset it trains on
    epochs: int = Field(20, ge=1)
    batch_size: int = Field(64, ge=1)
    lr: float = Field(1e-3, gt=0)
    patience: int | None = Field(5, ge=1)
    val_fraction: float = Field(0.2, ge=0, lt=1)
    val_by: Literal["auto", "recording", "block"] = "auto"   # auto: by recording with 3+ recordings, else by block
    labels: Literal["auto"] | dict[str, list[float]] = "auto"
    seed: int = 0
    augment: AugmentSpec = AugmentSpec()


class HardwareSpec(Strict):
    device: Literal["cpu", "cuda"] = "cpu"
    threads: int | None = Field(None, ge=1)


class OfflineSpec(Strict):
    data: str = "test"            # the dataset offline metrics are measured on
    batch: int = Field(64, ge=1)  # batch size of the throughput measurement


class OnlineSpec(Strict):
    timing: Literal["latency", "lockstep", "realtime"] = "latency"
    directions: list[Literal["cw", "ccw"]] = Field(["cw"], min_length=1)
    repetitions: int = Field(1, ge=1)
    control_hz: float = Field(20.0, gt=0)
    timeout_s: float | None = Field(None, gt=0, description="default: BehaviorMetrics' per-circuit timeout")
    references: list[Literal["explicit", "expert"]] = ["explicit", "expert"]
    video: bool = False


class ReportSpec(Strict):
    folder: str = "reports"
    compare_with: str | None = None   # a study whose claims are checked (pilotlab.report.studies)

    @model_validator(mode="after")
    def _known_study(self):
        from pilotlab.report.studies import STUDIES
        if self.compare_with is not None and self.compare_with not in STUDIES:
            raise ValueError(f"unknown study {self.compare_with!r}{did_you_mean(self.compare_with, STUDIES)}; "
                             f"known: {', '.join(STUDIES.names())}")
        return self


SECTIONS: dict[str, tuple[Any, Any]] = {
    "datasets": (dict[str, DatasetSpec], ...),
    "circuits": (dict[str, CircuitSpec], {}),
    "models": (dict[str, ModelSpec], ...),
    "strategies": (dict[str, dict[str, Any]], {}),
    "hardware": (dict[str, HardwareSpec], {}),
    "offline": (OfflineSpec, OfflineSpec()),
    "online": (OnlineSpec, OnlineSpec()),
    "report": (ReportSpec, ReportSpec()),
}
