"""Jobs as plain data, and their content keys.

A job is a frozen spec: its kind, a human name, JSON-able params, the jobs it depends on (by role,
fixed at construction) and the user files it reads. Its key is a sha256 over canonical JSON of all
of that plus the fingerprint of the code that implements its kind; equal inputs give equal keys,
so jobs are shared wherever their inputs are equal.
"""
from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Any

from matrix.errors import MatrixError
from matrix.fingerprint import hash_path
from matrix.kinds import KINDS

KEY_FORMAT = 1


class UnserialisableError(MatrixError):
    """A job parameter cannot be written as canonical JSON."""


def canonical_json(value: Any) -> str:
    """Sorted keys, no spaces, UTF-8; only JSON's own types (tuples as lists); NaN is an error."""
    _check_json(value, "")
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


_SCALARS = (str, int, bool, type(None))


def _check_json(value: Any, where: str) -> None:
    """Raise UnserialisableError naming where `value` is not plain JSON. The walk keeps no path (it
    runs over every parameter of every job a plan makes); only a failure walks again to name it."""
    if not _is_json(value):
        _find_unserialisable(value, where)


def _is_json(value: Any) -> bool:
    kind = type(value)
    if kind in _SCALARS:
        return True
    if kind is float:
        return math.isfinite(value)
    if kind is dict:
        for key, item in value.items():
            if type(key) is not str or (type(item) not in _SCALARS and not _is_json(item)):
                return False
        return True
    if kind is list or kind is tuple:
        for item in value:
            if type(item) not in _SCALARS and not _is_json(item):
                return False
        return True
    return _find_unserialisable(value, "", raise_error=False)   # subclasses and other Mappings


def _find_unserialisable(value: Any, where: str, raise_error: bool = True) -> bool:
    """The slow walk with paths: raises (or returns False) at the first value JSON cannot hold."""
    try:
        _walk(value, where)
    except UnserialisableError:
        if raise_error:
            raise
        return False
    return True


def _walk(value: Any, where: str) -> None:
    if value is None or isinstance(value, (bool, int, str)):
        return
    if isinstance(value, float):
        if not math.isfinite(value):
            raise UnserialisableError(f"{where or 'value'}: {value} has no JSON form")
        return
    if isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            _walk(item, f"{where}[{i}]")
        return
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str):
                raise UnserialisableError(f"{where or 'value'}: mapping key {key!r} is not a string")
            _walk(item, f"{where}.{key}" if where else key)
        return
    raise UnserialisableError(f"{where or 'value'}: {type(value).__name__} {value!r:.60} cannot be "
                              "serialised to JSON; use str, int, float, bool, None, lists and dicts")


def make_key(kind: str, params: Mapping[str, Any], deps: Mapping[str, Any],
             inputs: Mapping[str, str], code: str) -> str:
    """The job key: sha256 hex of canonical JSON. Golden tests pin this format."""
    payload = {"format": KEY_FORMAT, "kind": kind, "params": params, "deps": deps,
               "inputs": inputs, "code": code}
    return hashlib.sha256(canonical_json(payload).encode()).hexdigest()


@dataclass(frozen=True)
class InputFile:
    path: str
    sha256: str


def input_file(path: str) -> InputFile:
    """An input file (or bag folder) with its content hash, for `Job(inputs=...)`."""
    return InputFile(str(path), hash_path(path))


@dataclass(frozen=True, eq=False)
class Job:
    kind: str
    name: str                                           # unique within a plan, e.g. "train pilotnet"
    params: Mapping[str, Any] = field(default_factory=dict)
    deps: Mapping[str, Job | tuple[Job, ...]] = field(default_factory=dict)
    inputs: Mapping[str, InputFile] = field(default_factory=dict)
    labels: Mapping[str, Any] = field(default_factory=dict)   # descriptive only, not in the key

    def __post_init__(self):
        _check_json(self.params, "")  # fail at construction, naming nothing random (no text: the key makes it)
        deps = {role: tuple(d) if isinstance(d, (list, tuple)) else d for role, d in self.deps.items()}
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))
        object.__setattr__(self, "deps", MappingProxyType(deps))
        object.__setattr__(self, "inputs", MappingProxyType(dict(self.inputs)))
        object.__setattr__(self, "labels", MappingProxyType(dict(self.labels)))

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Job) and other.key == self.key

    def __repr__(self) -> str:
        return f"Job({self.kind!r}, {self.name!r}, {self.key[:10]})"

    @cached_property
    def code(self) -> str:
        return KINDS.get(self.kind).fingerprint(self.params)

    @cached_property
    def key(self) -> str:
        return make_key(self.kind, dict(self.params), self.dep_keys(),
                        {role: f.sha256 for role, f in self.inputs.items()}, self.code)

    def dep_keys(self) -> dict[str, str | list[str]]:
        return {role: [d.key for d in dep] if isinstance(dep, tuple) else dep.key
                for role, dep in self.deps.items()}

    def dep_jobs(self) -> list[Job]:
        return [d for dep in self.deps.values() for d in (dep if isinstance(dep, tuple) else (dep,))]

    def spec(self) -> dict[str, Any]:
        """What `spec.json` holds: everything that went into the key, readable."""
        return {"key": self.key, "kind": self.kind, "name": self.name, "params": dict(self.params),
                "deps": self.dep_keys(), "dep_names": {d.key: d.name for d in self.dep_jobs()},
                "inputs": {role: {"path": f.path, "sha256": f.sha256} for role, f in self.inputs.items()},
                "code": self.code, "labels": dict(self.labels)}
