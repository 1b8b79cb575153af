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

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, field_validator, model_validator

from matrix.errors import did_you_mean
from pilotlab.hardware import HardwareOptions
from pilotlab.specs.base import Direction, Spec
from pilotlab.specs.timing import OfflineSettings
from pilotlab.specs.online import LapSettings, ToleranceSpec
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


# what a lap cell is named by, for `tolerance: {only: ...}`
CELL_AXES = ("model", "strategy", "hardware", "circuit", "world", "direction")


def _cell_entry(entry: Any) -> dict[str, list[str]]:
    """{axis: [names]} from a partial cell whose values are names or lists of names."""
    if not isinstance(entry, dict) or not entry:
        raise ValueError(f"each entry of only is a partial cell, e.g. {{circuit: montreal, strategy: baseline}}; "
                         f"got {entry!r}")
    for axis, value in entry.items():
        if axis not in CELL_AXES:
            raise ValueError(f"{axis!r} is not an axis of a lap cell{did_you_mean(str(axis), CELL_AXES)}; "
                             f"known: {', '.join(CELL_AXES)}")
        names = value if isinstance(value, list) else [value]
        if not names or not all(isinstance(name, str) and name for name in names):
            raise ValueError(f"{axis}: {value!r}: give a name or a list of names")
    return {axis: list(value) if isinstance(value, list) else [value] for axis, value in entry.items()}


CellEntry = Annotated[dict[str, list[str]], BeforeValidator(_cell_entry)]


class ToleranceSection(ToleranceSpec):
    """The recipe's tolerance search: the search's settings (the laps' own, ToleranceSpec) and the lap
    cells it is made for. Each searched cell drives its lap again and again (the study's Montreal
    searches were two thirds of its laps' time), so a recipe can keep it to the cells whose tolerance it
    reads: `only: [{circuit: simple_circuit}, {circuit: montreal, strategy: baseline}]`."""
    only: list[CellEntry] | None = Field(
        None, description="the lap cells searched: a cell is searched when it has every value one entry names "
                          "(each a name or a list of names, by model, strategy, hardware, circuit, world or "
                          "direction; the reference brains are model `reference`); default: every lap cell")

    @field_validator("only", mode="before")
    @classmethod
    def _entries_name_cells(cls, only: Any) -> Any:
        if only is None:
            return only
        if not isinstance(only, list) or not only:
            raise ValueError(f"only is a list of partial cells, e.g. [{{circuit: simple_circuit}}]; got {only!r}")
        return only     # each entry checked by CellEntry: an error names its index (only.1) and its line

    @property
    def search(self) -> ToleranceSpec:
        """The settings a searched lap runs with (its key: `only` is the planner's, not the lap's)."""
        return ToleranceSpec(**self.model_dump(exclude={"only"}))

    def matches(self, cell: dict[str, str]) -> list[int]:
        """The indices of the `only` entries `cell` ({axis: name}) has every value of; [-1] without `only`."""
        if self.only is None:
            return [-1]
        return [i for i, entry in enumerate(self.only)
                if all(cell.get(axis) in names for axis, names in entry.items())]



class OnlineSection(LapSettings):
    directions: list[Direction] = Field(["cw"], min_length=1)
    tolerance: ToleranceSection | None = Field(None, description="search the largest injected latency at which the "
                                                                  "lap is still completed (true: the default search, "
                                                                  "on every lap cell)")
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
