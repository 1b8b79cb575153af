"""Command-line options built from a params model (pilotlab.specs), so `pilotlab record` and
`pilotlab drive` take the same names, defaults and checks as the recipe and the jobs.

    add_spec_options(parser, RecordSpec, ["laps", "seed", "noise"], flags={"rate_hz": ["--rate"]})
    spec = spec_from_args(RecordSpec, args, circuit=args.circuit)   # a bad value: one line naming the option
"""
from __future__ import annotations

import argparse
import re
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Any

import pydantic

from matrix.errors import shown
from pilotlab.errors import PilotlabError


def add_spec_options(parser: argparse.ArgumentParser, model: type[pydantic.BaseModel], fields: Iterable[str],
                     flags: Mapping[str, list[str]] | None = None) -> None:
    """An option per field: its type, choices, help and default come from the model. Options not
    given stay unset, so the model's own default applies."""
    flags = dict(flags or {})
    for name in fields:
        info = model.model_fields[name]
        names = flags.get(name) or [option_name(name)]
        parser.add_argument(*names, dest=name, default=argparse.SUPPRESS, help=help_of(info),
                            **_kind_of(info.annotation))
        parser.set_defaults(**{f"_flag_{name}": names[0]})


def option_name(field: str) -> str:
    return "--" + field.replace("_", "-")


def spec_from_args(model: type[pydantic.BaseModel], args: argparse.Namespace, **values: Any):
    """The model from the options given (and `values`); a bad value is a PilotlabError naming its option."""
    given = {name: getattr(args, name) for name in model.model_fields
             if hasattr(args, f"_flag_{name}") and hasattr(args, name)}
    try:
        return model.model_validate({**given, **values})
    except pydantic.ValidationError as error:
        first = error.errors(include_url=False)[0]
        message = in_flags(first["msg"].removeprefix("Value error, "), model, args)
        if not first["loc"]:   # a check across options: its message alone (the input is every option given)
            raise PilotlabError(message) from None
        field = str(first["loc"][0])
        flag = getattr(args, f"_flag_{field}", None) or option_name(field)
        where = ".".join(str(part) for part in first["loc"][1:] if not _is_union_tag(part))
        raise PilotlabError(f"{flag}{' ' + where if where else ''}: {message} (got {shown(first.get('input'), 60)})") \
            from None


def in_flags(message: str, model: type[pydantic.BaseModel], args: argparse.Namespace) -> str:
    """`message` with the fields it names as the command line names them (fixed_inference_ms ->
    --fixed-inference-ms, rate_hz -> --rate): a person typed the flags (outside test)."""
    for name in sorted((n for n in model.model_fields if "_" in n), key=len, reverse=True):   # not prose words
        flag = getattr(args, f"_flag_{name}", None)
        if flag is not None:
            message = re.sub(rf"(?<![\w-]){re.escape(name)}(?!\w)", flag, message)
    return message


def _is_union_tag(part) -> bool:
    """pydantic names the arm of a union it tried ("float", "literal['random']"): not a key."""
    return isinstance(part, str) and (part in ("float", "int", "str", "bool") or "[" in part)


def help_of(info) -> str:
    default = info.default
    shown = "" if default is None or isinstance(default, pydantic.BaseModel) else f" (default {default})"
    return (info.description or "") + shown


def _kind_of(annotation: Any) -> dict[str, Any]:
    arms = [a for a in _arms(annotation) if a is not type(None)]
    if arms == [bool]:
        return {"action": argparse.BooleanOptionalAction}
    literals = [value for arm in arms if typing.get_origin(arm) is typing.Literal for value in typing.get_args(arm)]
    if literals and len(arms) == 1:
        return {"choices": literals}
    if arms in ([int], [float]):
        return {"type": arms[0], "metavar": arms[0].__name__.upper()}
    return {"metavar": "VALUE"}   # a union (e.g. metres or "random"): the model parses the text


def _arms(annotation: Any) -> tuple:
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return typing.get_args(annotation)
    return (annotation,)
