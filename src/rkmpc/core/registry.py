"""One registry pattern: named things (controllers, plants, cars, presets, faults, ...) and one error.

A :class:`Registry` maps names to entries in the order they were registered; looking up a name
it does not hold raises :class:`UnknownNameError` naming what was asked for, the closest known
names and every known name. Every registry of the package is one of these, so every unknown
name gets the same kind of message and the same exception type.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator, Mapping
from typing import Generic, TypeVar

from rkmpc.core.errors import ParameterError

__all__ = ["Registry", "UnknownNameError"]

T = TypeVar("T")


class UnknownNameError(ParameterError, KeyError):
    """A name that a registry does not hold.

    Parameters
    ----------
    kind : str
        What the registry holds (``"controller"``, ``"plant"``, ...).
    name : str
        The name asked for.
    known : sequence of str
        The names it holds.
    """

    def __init__(self, kind: str, name: object, known: list[str]) -> None:
        self.kind = kind
        self.name = name
        self.known = known
        close = difflib.get_close_matches(str(name), known, n=3, cutoff=0.6)
        hint = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
        super().__init__(f"unknown {kind} {name!r}; {hint}known: {', '.join(known)}")

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class Registry(Mapping[str, T], Generic[T]):
    """Entries by name, in registration order.

    Parameters
    ----------
    kind : str
        What the entries are, for messages (``"controller"``).
    entries : mapping of str to T, optional
        The first entries.
    """

    def __init__(self, kind: str, entries: Mapping[str, T] | None = None) -> None:
        self.kind = kind
        self._entries: dict[str, T] = {}
        for name, entry in (entries or {}).items():
            self.register(name, entry)

    def register(self, name: str, entry: T) -> T:
        """Add ``entry`` under ``name`` (a non-empty string not registered yet); returns it."""
        if not isinstance(name, str) or not name:
            raise ParameterError(f"a {self.kind} name must be a non-empty string, got {name!r}")
        if name in self._entries:
            raise ParameterError(f"a {self.kind} named {name!r} is already registered")
        self._entries[name] = entry
        return entry

    def __getitem__(self, name: str) -> T:
        try:
            return self._entries[name]
        except (KeyError, TypeError):
            raise UnknownNameError(self.kind, name, list(self._entries)) from None

    def check(self, name: str) -> str:
        """``name`` when it is registered, else :class:`UnknownNameError`."""
        self[name]
        return name

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {list(self._entries)})"
