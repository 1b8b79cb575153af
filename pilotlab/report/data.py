"""What a report is made of: `ReportData`, built by the caller from job results (plain dicts).

    data = ReportData.from_dict({
        "recipe_name": "quickstart", "description": "...", "recipe_text": yaml_text,
        "versions": package_versions(), "host": Host.detect(), "date": "2025-01-31T12:00:00",
        "rows": [
            {"model": "pilotnet", "strategy": "baseline", "hardware": "cpu1", "kind": "offline",
             "test_set": "simple_circuit", "job_keys": {"offline": "3f2a..."},
             "size_mb": 6.1, "mse": 0.078, "latency_ms": 2.2},          # metrics flat or under "metrics"
            {"model": "pilotnet", "strategy": "static_quant", "hardware": "cuda", "kind": "offline",
             "status": "not_applicable", "reason": "fbgemm kernels run on CPU only"},
            {"model": "pilotnet", "strategy": "baseline", "hardware": "cpu1", "kind": "online",
             "circuit": "montreal", "direction": "cw", "lap_completed": True, "average_speed": 8.4,
             "trajectory": "/path/to/trajectory.png",
             "spread": {"average_speed": {"std": 0.12, "min": 8.3, "max": 8.5, "runs": 3},   # repeated laps
                        "lap_completed": {"completed": 3, "runs": 3}}},
        ],
        "histories": {"pilotnet": [{"epoch": 1, "train_loss": 0.2, "val_loss": 0.3}, ...]},
    })

Metric names are exactly those of `pilotlab.columns`; an unknown name is an error that names the
closest known one (`pick_metrics(job_result)` keeps only the metric keys of a job's result dict).
A metric that was not measured is left out (None and NaN count as left out): the report shows it as
missing, never as 0. A row whose status is not "ok" needs a one-line reason and shows no numbers.
An online row whose lap was repeated from several start points carries the online job's `spread`
({metric: {std, min, max, runs}}, lap_completed: {completed, runs}; `pick_spread(job_result)`): its
metrics are then the means, and the report shows `mean ± std` and how many laps were completed.
An offline row whose timing stayed disturbed carries the offline job's `unstable` (its timing job's; {metric: reason},
`pick_unstable(job_result)`): the report marks those figures, shows their spread, and draws no
summary line or verdict from them (`timing_issue` says why two rows' timings cannot be compared).
One whose single-thread timing is the calls' thread CPU time, the wall clock being disturbed, carries
the job's `cpu_time` ({metric: reason}, `pick_cpu_time(job_result)`): the report labels those figures.
`baseline` (default "baseline") names the strategy the ratios are taken against.
"""
from __future__ import annotations

import math
import os
import platform
from collections.abc import Iterable, Mapping
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any, Literal

from pydantic import (BaseModel, ConfigDict, Field, StrictBool, ValidationError, ValidationInfo, field_validator,
                      model_validator)

from pilotlab.columns import BY_NAME
from pilotlab.errors import PilotlabError
from pilotlab.cpuinfo import cpu_model
from pilotlab.hardware import gpu_name
from matrix.errors import did_you_mean

Kind = Literal["offline", "online"]
Status = Literal["ok", "not_applicable", "failed", "not_run"]
MetricValue = StrictBool | int | float
DEFAULT_PACKAGES = ("pilotlab", "torch", "torchao", "onnxruntime", "onnx", "numpy", "pybullet",
                    "opencv-python-headless")
# "world" last: results.csv's earlier columns keep their places
ROW_FIELDS = ("model", "strategy", "hardware", "circuit", "direction", "test_set", "kind", "status", "reason", "world")
TIMED = ("latency_ms", "throughput_ips")    # the figures an offline job may mark unstable
UNSTABLE_COLUMNS = tuple(f"{name}_unstable" for name in TIMED)
CPU_TIME_COLUMNS = tuple(f"{name}_cpu_time" for name in TIMED)


class ReportDataError(PilotlabError):
    """The data handed to the report writer is not well formed; the message says which row and field."""


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", defer_build=True)


class Host(_Frozen):
    """The machine the timings were measured on."""
    cpu: str = "unknown CPU"
    cores: int | None = None
    gpu: str | None = None          # None: no GPU was used or present
    os: str = ""
    # profiles that stand for another machine (worker_resource) -> the host that timed them (an outside test:
    # the report named only the planning host, never the Jetson its jetson rows were timed on)
    elsewhere: dict[str, str] = Field(default_factory=dict)

    @classmethod
    def detect(cls) -> Host:
        """This machine: CPU model, logical cores, the CUDA device (as the timing jobs fingerprint it)."""
        return cls(cpu=cpu_model() or "unknown CPU", cores=os.cpu_count(), gpu=gpu_name(), os=platform.platform(terse=True))

    def describe(self) -> str:
        cores = f", {self.cores} cores" if self.cores else ""
        others = "".join(f"; {profile} timed on {host}" for profile, host in self.elsewhere.items())
        return f"{self.cpu}{cores}; GPU: {self.gpu or 'none'}{others}"


class HistoryPoint(BaseModel):
    """One epoch of training, as `pilotlab.training.fit` returns it (other keys are ignored)."""
    model_config = ConfigDict(frozen=True, extra="ignore", defer_build=True)
    epoch: int
    train_loss: float
    val_loss: float | None = None
    precision: str | None = None          # fp32 or bf16 (mixed); None in results older than the setting


class Spread(_Frozen):
    """How one metric varied over repeated runs: the online job's `spread[metric]`."""
    runs: int                                # runs that measured it (lap_seconds: the completed laps)
    std: float | None = None                 # sample standard deviation (0 for one run)
    min: float | None = None
    max: float | None = None
    completed: int | None = None             # lap_completed only: the runs that completed the lap

    @field_validator("std", "min", "max", mode="before")
    @classmethod
    def _unmeasured_is_none(cls, value: Any) -> Any:
        return None if _unmeasured(value) else value


class TolerancePoint(_Frozen):
    """One lap of a latency tolerance search (pilotlab.online.tolerance): the online job's
    `tolerance_laps[i]` (other keys are ignored)."""
    model_config = ConfigDict(frozen=True, extra="ignore", defer_build=True)
    injected_ms: float
    lap_completed: bool
    position_deviation_mae_m: float | None = None
    bm_position_deviation_mae: float | None = None


class Claim(_Frozen):
    """A published claim checked against this report's figures (pilotlab.report.studies)."""
    claim: str
    verdict: Literal["holds", "does not hold", "not testable here"]
    found: str


class ReportRow(_Frozen):
    """One evaluated cell: an offline evaluation or a closed-loop lap of one optimised model."""
    model: str
    strategy: str
    hardware: str
    kind: Kind
    status: Status = "ok"
    reason: str = ""                         # one line; required unless status is "ok"
    circuit: str | None = None               # online rows: the circuit driven (in a BM world: the world)
    world: str | None = None                 # a BehaviorMetrics world the row was evaluated in (pilotlab.worlds)
    direction: str | None = None             # online rows: "cw" / "ccw" where it matters
    test_set: str | None = None              # offline rows: the held-out recordings' name
    job_keys: dict[str, str] = Field(default_factory=dict)   # job kind (or role) -> store key
    metrics: dict[str, MetricValue] = Field(default_factory=dict)
    trajectory: Path | None = None           # online rows: PNG of the path over the red line
    spread: dict[str, Spread] = Field(default_factory=dict)  # online rows: metric -> its spread over runs
    unstable: dict[str, str] = Field(default_factory=dict)   # timed metric -> why unstable (a lap: its replayed one)
    cpu_time: dict[str, str] = Field(default_factory=dict)   # offline rows: timed metric -> why it is CPU time
    tolerance: tuple[TolerancePoint, ...] = ()              # online rows: the laps of the tolerance search
    tolerance_at_least: bool = False         # the lap was still completed at the search's largest latency
    latency_source: str | None = None        # online rows: where the replayed latencies came from
    trained_on: tuple[str, ...] = ()         # offline rows: test recordings the network was trained on too
    runs: str | None = None                  # the built-in strategy that made the row's network (a recipe's
    options: dict[str, Any] = Field(default_factory=dict)   # name may stand for another: `use:`), its options

    @model_validator(mode="before")
    @classmethod
    def _gather_flat_metrics(cls, value: Any) -> Any:
        """Accept metrics at the top level (as job results carry them) as well as under "metrics"."""
        if not isinstance(value, Mapping):
            return value
        fields = cls.model_fields
        row = {k: v for k, v in value.items() if k in fields}
        flat = {k: v for k, v in value.items() if k not in fields}   # unknown names are reported as metrics
        row["metrics"] = {**dict(value.get("metrics") or {}), **flat}
        return row

    @field_validator("metrics", mode="before")
    @classmethod
    def _known_measured_metrics(cls, metrics: Mapping[str, Any]) -> dict[str, Any]:
        for name in metrics:
            if name not in BY_NAME:
                known = [*BY_NAME, *cls.model_fields]
                raise ValueError(f"unknown metric or field {name!r}{did_you_mean(name, known)}; "
                                 f"metric names are those of pilotlab/columns.py")
        return {k: v for k, v in metrics.items() if not _unmeasured(v)}

    @field_validator("spread", mode="before")
    @classmethod
    def _known_spread_metrics(cls, spread: Mapping[str, Any] | None) -> dict[str, Any]:
        for name in spread or {}:
            if name not in BY_NAME:
                raise ValueError(f"spread of unknown metric {name!r}{did_you_mean(name, list(BY_NAME))}; "
                                 f"metric names are those of pilotlab/columns.py")
        return dict(spread or {})

    @field_validator("unstable", "cpu_time", mode="before")
    @classmethod
    def _known_timed_metrics(cls, reasons: Mapping[str, Any] | None, info: ValidationInfo) -> dict[str, Any]:
        for name in reasons or {}:
            if name not in TIMED:
                raise ValueError(f"{info.field_name}: {name!r} is not a timed metric"
                                 f"{did_you_mean(name, list(TIMED))}")
        return {name: " ".join(str(reason).split()) for name, reason in (reasons or {}).items()}

    @field_validator("reason")
    @classmethod
    def _one_line(cls, reason: str) -> str:
        return " ".join(reason.split())

    @model_validator(mode="after")
    def _reason_when_not_ok(self) -> ReportRow:
        if self.status != "ok" and not self.reason:
            raise ValueError(f"a {self.status!r} row needs a one-line 'reason'")
        return self

    def get(self, name: str) -> MetricValue | None:
        """The metric's value, or None when it was not measured (or the cell did not run)."""
        return self.metrics.get(name) if self.status == "ok" else None

    def unstable_reason(self, name: str) -> str | None:
        """Why the timed metric `name` is unstable (its timing stayed disturbed), or None."""
        return self.unstable.get(name) if self.status == "ok" else None

    def cpu_time_reason(self, name: str) -> str | None:
        """Why the timed metric `name` is the calls' thread CPU time (the wall clock was disturbed), or None."""
        return self.cpu_time.get(name) if self.status == "ok" else None

    def spread_of(self, name: str) -> Spread | None:
        """The metric's spread when more than one run measured it (else None: a single value)."""
        spread = self.spread.get(name) if self.status == "ok" else None
        return spread if spread is not None and spread.runs > 1 else None

    @property
    def repetitions(self) -> int | None:
        """How many runs the row's figures come from (None when it does not say: one)."""
        if self.status != "ok" or not self.spread:
            return None
        laps = self.spread.get("lap_completed")
        return laps.runs if laps is not None else max(s.runs for s in self.spread.values())

    @property
    def place(self) -> str:
        """Where it was evaluated: the circuit (and direction) online, the test set offline."""
        if self.kind == "online":
            return " ".join(p for p in (self.circuit, self.direction) if p) or "—"
        return self.test_set or self.circuit or "test set"

    def flat(self) -> dict[str, Any]:
        """The tidy row as written to results.csv / results.json (metrics None when unmeasured), then
        `repetitions`, `repetitions_completed` (the runs that completed the lap) and, for each metric
        measured by more than one run, `<metric>_std`, `_min` and `_max` (see `spread_columns`)."""
        base = {name: getattr(self, name) for name in ROW_FIELDS}
        laps = self.spread.get("lap_completed") if self.status == "ok" else None
        repeated = {"repetitions": self.repetitions, "repetitions_completed": laps.completed if laps else None}
        for name in BY_NAME:
            spread = self.spread_of(name)
            if spread is not None and name != "lap_completed":
                repeated |= {f"{name}_std": spread.std, f"{name}_min": spread.min, f"{name}_max": spread.max}
        unstable = {f"{name}_unstable": self.unstable_reason(name) for name in TIMED}
        cpu_time = {f"{name}_cpu_time": self.cpu_time_reason(name) for name in TIMED}
        # last, so the earlier columns keep their places; "lost at 0" and "not searched" both leave the tolerance empty
        searched = {"latency_tolerance_searched": bool(self.tolerance) if self.kind == "online" else None}
        return {**base, **{name: self.get(name) for name in BY_NAME}, **unstable, **cpu_time, **repeated, **searched}


class ReportData(_Frozen):
    """Everything the report shows. Build it with `ReportData.from_dict` from plain dicts."""
    recipe_name: str
    description: str = ""
    recipe_text: str = ""
    versions: dict[str, str] = Field(default_factory=dict)
    host: Host = Field(default_factory=Host)
    date: datetime
    baseline: str = "baseline"               # the strategy the ratios are taken against
    rows: tuple[ReportRow, ...] = ()
    histories: dict[str, tuple[HistoryPoint, ...]] = Field(default_factory=dict)   # model -> epochs
    sources: dict[str, str] = Field(default_factory=dict)   # model -> where a model the user brought came from
    training_warnings: dict[str, list[str]] = Field(default_factory=dict)   # model -> its training's (too little data)
    training_data: dict[str, str] = Field(default_factory=dict)   # model -> what it was trained on, in words
    comparison_title: str = ""               # "Compared with the 2022 study", when the recipe asks for one
    comparison: tuple[Claim, ...] = ()
    training_worlds: dict[str, tuple[str, ...]] = Field(default_factory=dict)   # model -> worlds it was trained in
    # a name shown -> the other names of the matrix with its definition (planned once, its rows stand for them)
    same_as: dict[str, tuple[str, ...]] = Field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ReportData:
        """Validate plain data (see the module docstring); errors name the row and field."""
        try:
            return cls.model_validate(data)
        except ValidationError as error:
            raise ReportDataError(_describe(error, data)) from None

    def models(self) -> list[str]:
        return _unique(row.model for row in self.rows)

    def strategies(self) -> list[str]:
        """In recipe order, with the baseline first."""
        found = _unique(row.strategy for row in self.rows)
        return sorted(found, key=lambda s: s != self.baseline)

    def hardware(self) -> list[str]:
        return _unique(row.hardware for row in self.rows)

    def circuits(self) -> list[str]:
        return _unique(row.circuit for row in self.rows if row.circuit)

    def of_kind(self, kind: Kind) -> list[ReportRow]:
        return [row for row in self.rows if row.kind == kind]

    def spread_columns(self) -> list[str]:
        """The result columns after the metrics: repetitions and repetitions_completed, then std, min and
        max of each metric that some row measured more than once (columns.py order)."""
        measured = {name for row in self.rows for name in BY_NAME if row.spread_of(name)} - {"lap_completed",
                                                                                             "bm_lap_completed"}
        stats = [f"{name}_{stat}" for name in BY_NAME if name in measured for stat in ("std", "min", "max")]
        return ["repetitions", "repetitions_completed", *stats]


def pick_metrics(result: Mapping[str, Any]) -> dict[str, Any]:
    """The metrics of pilotlab/columns.py found in a job's result dict (other keys are left behind)."""
    return {name: value for name, value in result.items() if name in BY_NAME}


def pick_spread(result: Mapping[str, Any]) -> dict[str, Any]:
    """The spread over repeated runs of an online job's result, for the metrics of pilotlab/columns.py
    ({} when the result has none)."""
    spread = result.get("spread")
    if not isinstance(spread, Mapping):
        return {}
    return {name: dict(value) for name, value in spread.items() if name in BY_NAME and isinstance(value, Mapping)}


def pick_unstable(result: Mapping[str, Any], key: str = "unstable") -> dict[str, str]:
    """The offline job's timed metrics that stayed disturbed, with the reasons ({} when none)."""
    unstable = result.get(key)
    if not isinstance(unstable, Mapping):
        return {}
    return {name: str(reason) for name, reason in unstable.items() if name in TIMED}


def pick_cpu_time(result: Mapping[str, Any]) -> dict[str, str]:
    """The offline job's timed metrics that are the calls' thread CPU time, with the reasons ({} when none)."""
    return pick_unstable(result, "cpu_time")


def timing_issue(rows: Iterable[ReportRow], metric: str = "latency_ms") -> str | None:
    """Why the timed `metric` of `rows` cannot be compared, or None: one of them stayed disturbed
    (the per-call interference check of pilotlab.timing decides)."""
    timed = [r for r in rows if r.get(metric) is not None]
    several = len({r.model for r in timed}) > 1     # then say whose: every model has a baseline
    for row in timed:
        if reason := row.unstable_reason(metric):
            return f"{f'{row.model} · ' if several else ''}{row.strategy} ({row.hardware}): unstable: {reason}"
    return None


def package_versions(packages: Iterable[str] = DEFAULT_PACKAGES) -> dict[str, str]:
    """Installed versions of the packages that shape the results (missing ones are left out)."""
    versions = {"python": platform.python_version()}
    for name in packages:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


def _describe(error: ValidationError, data: Mapping[str, Any]) -> str:
    lines = []
    for problem in error.errors():
        where = ".".join(str(p) for p in problem["loc"])
        if problem["loc"][:1] == ("rows",) and len(problem["loc"]) > 1:
            where += _row_label(data, problem["loc"][1])
        lines.append(f"{where}: {problem['msg']}")
    return "report data is not valid: " + "; ".join(lines)


def _row_label(data: Mapping[str, Any], index: Any) -> str:
    try:
        row = data["rows"][index]
        return " (" + "/".join(str(row.get(k)) for k in ("model", "strategy", "hardware", "kind")) + ")"
    except (KeyError, IndexError, TypeError, AttributeError):
        return ""


def _unmeasured(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def _unique(values: Iterable[str | None]) -> list[str]:
    return [v for v in dict.fromkeys(values) if v is not None]
