"""A small typed registry: name -> entry, filled by decorators, with helpful errors.

Used by the domain for models, strategies, circuits and job kinds (as torchao's config -> handler
and Gymnasium's `register`): registering a name twice is an error, and an unknown name lists the
known ones with "did you mean".
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from matrix.errors import MatrixError, UnknownNameError

T = TypeVar("T")


class DuplicateNameError(MatrixError):
    """A name was registered twice."""


class Registry(Generic[T]):
    def __init__(self, what: str):
        self.what = what
        self._entries: dict[str, T] = {}

    def add(self, name: str, entry: T) -> T:
        if name in self._entries:
            raise DuplicateNameError(f"{self.what} {name!r} is registered twice; pick another name")
        self._entries[name] = entry
        return entry

    def replace(self, name: str, entry: T) -> T:
        """Put `entry` where the registered `name` was (an unknown name is an error, as `get` says it)."""
        self.get(name)
        self._entries[name] = entry
        return entry

    def register(self, name: str) -> Callable[[T], T]:
        """Decorator form: `@models.register("pilotnet")`."""
        return lambda entry: self.add(name, entry)

    def get(self, name: str) -> T:
        try:
            return self._entries[name]
        except KeyError:
            raise UnknownNameError(self.what, name, self._entries) from None

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> list[str]:
        return list(self._entries)

    def items(self) -> list[tuple[str, T]]:
        return list(self._entries.items())
