"""The domain's recipe sections (the engine validates `name`, `description` and `matrix`).

Each section that configures a job kind is built from that kind's params model (pilotlab.specs),
so the recipe, the job and the CLI share one set of names and defaults.

    datasets:    named datasets: recorded in the simulator, or the user's bags / DLS folders
    circuits:    extra circuits from CSV files of x,y points (the five JdeRobot ones are built in)
    models:      named networks with their training settings
    strategies:  options for strategies, or new names for a strategy with other options (`use:`)
    hardware:    named hardware profiles beside the built-in cpu, cpu1 and cuda
    offline:     offline evaluation settings: the test set (`data`), the timing jobs' throughput batch
    online:      closed-loop evaluation settings
    report:      where reports go
    worlds:      where BehaviorMetrics' worlds are (the `world` axis, datasets recorded in them)
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from matrix.errors import did_you_mean
from pilotlab.hardware import HardwareOptions
from pilotlab.specs.base import Direction, Spec
from pilotlab.specs.timing import OfflineSettings
from pilotlab.specs.online import LapSettings
from pilotlab.specs.record import RecordSettings
from pilotlab.specs.train import TrainSpec


def listed_once(values: list) -> list:
    """A list whose entries each name one thing: one listed twice is an error (an outside test's `directions:
    [cw, cw]` recorded the circuit twice and trained on each frame twice, without a word)."""
    twice = [value for i, value in enumerate(values) if value in values[:i]]
    if twice:
        raise ValueError(f"{twice[0]!r} is listed twice; list each once")
    return values


class RecordingsSpec(RecordSettings):
    """Drive circuits (pilotlab's own world) or BehaviorMetrics' worlds with the expert in the simulator
    and record rosbags (one per circuit or world and direction)."""
    circuits: list[str] = []
    worlds: list[str] = []
    directions: list[Direction] = Field(["cw"], min_length=1)

    _listed_once = field_validator("circuits", "worlds", "directions")(listed_once)

    @model_validator(mode="after")
    def _somewhere_to_drive(self):
        if not self.circuits and not self.worlds:
            raise ValueError("give `circuits` (pilotlab's own world) or `worlds` (BehaviorMetrics' worlds) to "
                             "record in")
        return self


class WorldsSpec(Spec):
    """Where BehaviorMetrics' worlds are (docs/worlds.md): relative to the recipe's folder; default
    $PILOTLAB_BM_ASSETS."""
    assets: str | None = None


class TopicsSpec(Spec):
    image: str | None = None
    command: str | None = None


class DatasetSpec(Spec):
    record: RecordingsSpec | None = None
    bags: list[str] = []          # ROS1 .bag files or ROS2 bag folders
    folders: list[str] = []       # DeepLearningStudio folders (<n>.png + data.csv)
    topics: TopicsSpec = TopicsSpec()

    _listed_once = field_validator("bags", "folders")(listed_once)

    @model_validator(mode="after")
    def _has_a_source(self):
        if self.record is None and not self.bags and not self.folders:
            raise ValueError("a dataset needs `record`, `bags` or `folders`")
        return self


class CircuitSpec(Spec):
    """A circuit of the recipe's own: a closed loop (the last point joins the first) whose road is the
    default width (pilotlab.circuits.registry.DEFAULT_ROAD_WIDTH_M, 6 m); no other option is taken."""
    csv: str                      # x,y points of the centreline, in metres


class ModelSpec(TrainSpec):
    data: str = "train"           # the dataset it trains on


class HardwareSpec(HardwareOptions):
    latency_file: str | None = None   # a device's measured latencies, replayed in the laps (pilotlab.online.latency)


class OfflineSection(OfflineSettings):
    data: str = "test"            # the dataset the offline MSE is measured on (the timing jobs never read it)


class OnlineSection(LapSettings):
    directions: list[Direction] = Field(["cw"], min_length=1)
    # Reference rows: the built-in brains, and brains users write ({name: file.py:Class}, docs/brains.md).
    references: list[Literal["explicit", "expert"] | dict[str, str]] = ["explicit", "expert"]

    _listed_once = field_validator("directions")(listed_once)

    @field_validator("references")
    @classmethod
    def _user_brains(cls, references: list) -> list:
        names: list[str] = []
        for entry in references:
            name = entry
            if isinstance(entry, dict):
                if len(entry) != 1:
                    raise ValueError("a brain of yours is one entry {name: file.py:Class}, e.g. "
                                     "{mine: brains/mine.py:MyBrain}")
                (name, spec), = entry.items()
                if name in ("explicit", "expert"):
                    raise ValueError(f"{name!r} is a built-in reference brain; give your brain another name")
                if ":" not in spec:
                    raise ValueError(f"{name}: {spec!r}: name your brain as file.py:Class or module:Class")
            if name in names:
                raise ValueError(f"the reference {name!r} is listed twice")
            names.append(name)
        return references


class ReportSpec(Spec):
    folder: str = "reports"
    compare_with: str | None = None   # a study whose claims are checked (pilotlab.report.studies)

    @field_validator("compare_with")   # (a field's validator: the error is said at report.compare_with)
    @classmethod
    def _known_study(cls, study):
        if study is None:   # (the studies' checks are imported only for a comparison)
            return study
        from pilotlab.report.studies import STUDIES
        if study not in STUDIES:
            raise ValueError(f"unknown study {study!r}{did_you_mean(study, STUDIES)}; known: {', '.join(STUDIES.names())}")
        return study


SECTIONS: dict[str, tuple[Any, Any]] = {
    "datasets": (dict[str, DatasetSpec], ...),
    "circuits": (dict[str, CircuitSpec], {}),
    "models": (dict[str, ModelSpec], ...),
    "strategies": (dict[str, dict[str, Any]], {}),
    "hardware": (dict[str, HardwareSpec], {}),
    "offline": (OfflineSection, OfflineSection()),
    "online": (OnlineSection, OnlineSection()),
    "report": (ReportSpec, ReportSpec()),
    "worlds": (WorldsSpec, WorldsSpec()),
}
