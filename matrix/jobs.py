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
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from matrix.errors import MatrixError
from matrix.fingerprint import cache_generation
from matrix.inputhash import hash_path
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
    return _key_of(kind, canonical_json(params), _names(deps), _names(inputs), code)


def _key_of(kind: str, params_json: str, deps_json: str, inputs_json: str, code: str) -> str:
    """make_key with its parts written already: canonical JSON of the payload is its parts' canonical
    JSON in sorted key order, so params shared by many jobs are written once, not once a job."""
    text = (f'{{"code":{_string(code)},"deps":{deps_json},"format":{KEY_FORMAT},"inputs":{inputs_json},'
            f'"kind":{_string(kind)},"params":{params_json}}}')
    return hashlib.sha256(text.encode()).hexdigest()


_string = json.encoder.encode_basestring   # a str as json.dumps(ensure_ascii=False) writes it


def _names(mapping: Mapping[str, Any]) -> str:
    """Canonical JSON of {role: name or [names]} (the keys' deps and inputs), written directly: planning
    writes one per job."""
    if not mapping:
        return "{}"
    return "{" + ",".join([_string(role) + ":" + (_string(value) if type(value) is str else _list(value))
                           for role, value in sorted(mapping.items())]) + "}"


def _dep_keys_json(deps: Mapping[str, Job | tuple[Job, ...]]) -> str:
    """_names of a job's {role: dep key or [dep keys]}, written from the jobs (no dict made on the way)."""
    if not deps:
        return "{}"
    return "{" + ",".join([_string(role) + ":" + ("[" + ",".join([_string(d.key) for d in dep]) + "]"
                                                   if type(dep) is tuple else _string(dep.key))
                           for role, dep in sorted(deps.items())]) + "}"


def _list(value: Any) -> str:
    if type(value) is list and all(type(item) is str for item in value):
        return "[" + ",".join(map(_string, value)) + "]"
    return _dumps(value)


def _dumps(value: Any) -> str:   # the keys' own parts: plain strings, lists and dicts of them
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


class Params(Mapping):
    """A job's params: read-only, checked to be plain JSON and written as canonical JSON once, however
    many jobs share them (a planner builds the params of every lap on one circuit once: `Job(params=`
    one Params object`)`)."""
    __slots__ = ("_data", "_json", "_codes")

    def __init__(self, data: Mapping[str, Any]):
        _check_json(data, "")  # fail at construction, naming nothing random (no text: the key makes it)
        self._data: dict[str, Any] = dict(data)
        self._json: str | None = None
        self._codes: dict[tuple[str, int], str] = {}   # (kind, code cache generation) -> its code fingerprint

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self):
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def get(self, key: str, default: Any = None) -> Any:
        return self._data.get(key, default)

    def __repr__(self) -> str:
        return f"Params({self._data!r})"

    @property
    def json(self) -> str:
        if self._json is None:
            self._json = _dumps(self._data)
        return self._json

    def code(self, kind: str) -> str:
        """The code fingerprint of a `kind` job with these params (asked once, however many jobs share them)."""
        slot = (kind, cache_generation())
        if slot not in self._codes:
            self._codes[slot] = KINDS.get(kind).fingerprint(self._data, self.json)
        return self._codes[slot]


@dataclass(frozen=True)
class InputFile:
    path: str
    sha256: str
    # an input hashed from several files (a module and the modules it imports): (name, sha256) of each, so
    # that `plan` can say which one changed; kept in spec.json, not in the key (sha256 covers them)
    parts: tuple[tuple[str, str], ...] = ()

    def record(self) -> dict[str, Any]:
        return {"path": self.path, "sha256": self.sha256, **({"parts": dict(self.parts)} if self.parts else {})}


def spec_dep_keys(deps: dict[str, str | list[str]]) -> list[str]:
    """Every dependency key of a stored spec's `deps` (role -> key, or keys: `Job.dep_keys`)."""
    return [key for value in deps.values() for key in (value if isinstance(value, list) else [value])]


def input_file(path: str) -> InputFile:
    """An input file (or bag folder) with its content hash, for `Job(inputs=...)`."""
    return InputFile(str(path), hash_path(path))


class _once:
    """functools.cached_property without its lock (Python 3.11 takes one on each first read; planning
    reads a key and a code per job)."""

    def __init__(self, function):
        self.function, self.name, self.__doc__ = function, function.__name__, function.__doc__

    def __get__(self, instance, owner=None):
        if instance is None:
            return self
        value = instance.__dict__[self.name] = self.function(instance)   # found there from now on
        return value


@dataclass(frozen=True, eq=False, init=False)
class Job:
    kind: str
    name: str                                           # unique within a plan, e.g. "train pilotnet"
    params: Params                                      # a Params is shared as it is, other mappings made one
    deps: Mapping[str, Job | tuple[Job, ...]]
    inputs: Mapping[str, InputFile]
    labels: Mapping[str, Any]                           # descriptive only, not in the key

    def __init__(self, kind: str, name: str, params: Mapping[str, Any] | None = None,
                 deps: Mapping[str, Job | tuple[Job, ...] | list[Job]] | None = None,
                 inputs: Mapping[str, InputFile] | None = None, labels: Mapping[str, Any] | None = None):
        # Written straight into the instance (a frozen dataclass's __init__ goes through object.__setattr__
        # once a field; a plan makes a job per cell).
        self.__dict__.update(
            kind=kind, name=name, params=params if type(params) is Params else Params(params or {}),
            deps=MappingProxyType({role: tuple(d) if isinstance(d, (list, tuple)) else d
                                   for role, d in (deps or {}).items()}),
            inputs=MappingProxyType(dict(inputs or {})), labels=MappingProxyType(dict(labels or {})))

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Job) and other.key == self.key

    def __repr__(self) -> str:
        return f"Job({self.kind!r}, {self.name!r}, {self.key[:10]})"

    @_once
    def code(self) -> str:
        return self.params.code(self.kind)

    @_once
    def key(self) -> str:
        # the deps written straight from the jobs (a plan makes a key a job; a test pins it to make_key)
        return _key_of(self.kind, self.params.json, _dep_keys_json(self.deps),
                       _names({role: f.sha256 for role, f in self.inputs.items()}), self.code)

    def dep_keys(self) -> dict[str, str | list[str]]:
        return {role: [d.key for d in dep] if isinstance(dep, tuple) else dep.key
                for role, dep in self.deps.items()}

    def dep_jobs(self) -> list[Job]:
        return [d for dep in self.deps.values() for d in role_jobs(dep)]

    def spec(self) -> dict[str, Any]:
        """What `spec.json` holds: everything that went into the key, readable."""
        return {"key": self.key, "kind": self.kind, "name": self.name, "params": dict(self.params),
                "deps": self.dep_keys(), "dep_names": {d.key: d.name for d in self.dep_jobs()},
                "inputs": {role: f.record() for role, f in self.inputs.items()},
                "code": self.code, "labels": dict(self.labels)}


def role_jobs(dep: Job | tuple[Job, ...]) -> tuple[Job, ...]:
    """The jobs of one dependency role: a group as it is, one job as a group of one."""
    return dep if isinstance(dep, tuple) else (dep,)
