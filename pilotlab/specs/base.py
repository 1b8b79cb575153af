"""What every params model shares: frozen, unknown keys rejected, errors in pilotlab's words."""
from __future__ import annotations

import dataclasses
import functools
import math
import re
import types
import typing
from typing import Any, Literal

import pydantic
from pydantic import Field

from matrix.errors import did_you_mean
from matrix.kinds import params_problem
from pilotlab.errors import PilotlabError

CONTROL_HZ = 20.0          # BehaviorMetrics' 50 ms brain cycle: commands and odometry per simulated second
LATENCY_LIMIT_MS = 60_000.0   # a minute per brain iteration, the most a lap's latency may be (1e7 ms ran for minutes)
Direction = Literal["cw", "ccw"]


USER_CODE = re.compile(r".:[A-Za-z_][\w.]*$")   # file.py:Class or module:Class (pilotlab.usercode)


def user_code_name(value: str | None) -> str | None:
    """A field naming user code: the class after a colon (a regex's "should match pattern" said nothing)."""
    if value is not None and not USER_CODE.search(value):
        raise ValueError(f"{value!r}: name your code as file.py:Class or module:Class (the class after a colon)")
    return value


class Spec(pydantic.BaseModel):
    """A frozen settings model. In a recipe, a bad value is the recipe's error (file, line, key);
    as job params, the job's (`from_job_params`); built directly, pydantic's ValidationError, which
    `spec_problem` words in one line (the CLI does so)."""
    model_config = pydantic.ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, defer_build=True)

    @classmethod
    def from_job_params(cls, params: dict[str, Any], job: str):
        """The job's params as this model; a bad one is a PilotlabError naming the job."""
        try:
            return cls.model_validate(params)
        except pydantic.ValidationError as error:
            raise PilotlabError(f"{job}: {params_problem(error, cls)}") from None

    @pydantic.model_validator(mode="before")
    @classmethod
    def _no_bools_for_numbers(cls, data: Any) -> Any:
        """YAML's `true` is not the number 1 (pydantic's lax mode would take it for one)."""
        if isinstance(data, dict):
            for name, value in data.items():
                info = cls.model_fields.get(name) if isinstance(name, str) else None
                if isinstance(value, bool) and info is not None and _takes_numbers_not_bools(info.annotation):
                    raise ValueError(f"{name}: {value} is not a number")
        return data

    def as_dict(self) -> dict[str, Any]:
        return self.model_dump(mode="json")


def spec_problem(error: pydantic.ValidationError) -> str:
    """One line for a settings model's complaint: 'RecordSpec: laps: Input should be greater than 0'."""
    return f"{error.title}: {params_problem(error, None)}"


def _takes_numbers_not_bools(annotation: Any) -> bool:
    arms = typing.get_args(annotation) if typing.get_origin(annotation) in (typing.Union, types.UnionType) \
        else (annotation,)
    return bool(set(arms) & {int, float}) and bool not in arms


class InWorld(pydantic.BaseModel):
    """A job that may run in one of BehaviorMetrics' own worlds (pilotlab.worlds) instead of pilotlab's
    own world. The world's files come as the job's input `world` (its .world file, keyed by the digest
    of everything the world reads). Without a world the field is left out of the params, so the keys of
    jobs in pilotlab's own world are what they were before worlds existed."""
    model_config = pydantic.ConfigDict(defer_build=True)
    world: str | None = Field(None, description="a BehaviorMetrics world (pilotlab world list) instead of the "
                                                "circuit in pilotlab's own world")

    @pydantic.model_serializer(mode="wrap")
    def _no_world_no_key(self, handler):
        data = handler(self)
        if isinstance(data, dict) and data.get("world", 0) is None:
            del data["world"]
        return data


class CameraSize(Spec):
    """The camera image the simulator renders (what the network's preprocessing crops and resizes)."""
    width: int = Field(640, ge=16, le=4096)
    height: int = Field(480, ge=16, le=4096)


@functools.cache
def _field_types(config_cls: type) -> dict[str, Any]:
    return typing.get_type_hints(config_cls)


@functools.cache
def _validator(annotation: Any) -> pydantic.TypeAdapter:
    """One validator per field type, not per config class: the ~30 configs have a dozen field types
    between them, and building a dataclass's validator (~2 ms) was most of what planning a recipe with
    options on every strategy cost."""
    return pydantic.TypeAdapter(annotation)


def _validated(config_cls: type, options: dict[str, Any]) -> dict[str, Any]:
    """The options as their fields' types, each checked as pydantic checks a dataclass field (lax)."""
    types_, values, problems = _field_types(config_cls), {}, []
    for name, value in options.items():
        if _is_numeric(types_[name]) and isinstance(value, (bool, str)):   # lax pydantic took '3' and true (1.0)
            problems.append(f"{name}: {str(value).lower() if isinstance(value, bool) else repr(value)} is not a "
                            "number" + (" (write it without quotes)" if _reads_as_number(value) else ""))
            continue
        try:
            values[name] = _validator(types_[name]).validate_python(value)
        except pydantic.ValidationError as error:
            problems += [f"{'.'.join(map(str, (name, *e['loc'])))}: {e['msg']} (got {e.get('input')!r:.80})"
                         for e in error.errors()]
    if problems:
        raise PilotlabError("; ".join(problems))
    return values


def _reads_as_number(value: Any) -> bool:
    try:
        return isinstance(value, str) and math.isfinite(float(value))
    except ValueError:
        return False


@functools.cache
def _is_numeric(annotation: Any) -> bool:
    """An int or float field (or one of them or None)."""
    kinds = set(typing.get_args(annotation)) - {type(None)} if isinstance(annotation, types.UnionType) or \
        typing.get_origin(annotation) is typing.Union else {annotation}
    return bool(kinds) and kinds <= {int, float}


def _common_problem(config, options: dict[str, Any]) -> str | None:
    """What is wrong with an option that means the same in every config, whichever registry it is of
    (a batch size of 0 failed deep in the job as a ZeroDivisionError): numbers are finite, batch sizes,
    frame counts, iterations and clusters at least 1, epochs at least 0, learning rates above 0."""
    for name in options:
        value = getattr(config, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        if not math.isfinite(value):
            return f"{name}: {value} is not a finite number"
        least = 1 if name in ("batch_size", "iterations", "clusters") or name.endswith("_frames") else \
            0 if name.endswith("epochs") else None
        if least is not None and value < least:
            return f"{name}: {value} must be at least {least}"
        if name == "lr" and value <= 0:
            return f"lr: {value} must be above 0"
    return None


def build_config(config_cls: type, options: dict[str, Any] | None, where: str):
    """A registry entry's frozen config dataclass (a strategy's, a model's, a brain's) from a
    recipe's options: unknown names get "did you mean", bad values the config's own words, and
    every message starts with `where` (e.g. "strategies.local_prune")."""
    options = dict(options or {})
    known = [f.name for f in dataclasses.fields(config_cls) if f.name != "version"]
    if unknown := sorted(set(options) - set(known) - {"version"}):   # a checkpoint's config keeps its version
        guesses = "".join(did_you_mean(option, known) for option in unknown)
        takes = f"known: {', '.join(known)}" if known else "it takes none"
        raise PilotlabError(f"{where}: unknown option(s) {', '.join(unknown)}{guesses}; {takes}")
    try:
        # No options: the config's own defaults, which need no validation; its __post_init__ checks run
        # all the same.
        if not options:
            return config_cls()
        config = config_cls(**_validated(config_cls, options))
        if problem := _common_problem(config, options):
            raise PilotlabError(problem)
        return config
    except PilotlabError as error:   # a bad value, or a config's own range check (its __post_init__)
        raise PilotlabError(f"{where}: {error}") from None
