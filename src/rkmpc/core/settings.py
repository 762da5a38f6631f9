"""Settings files read into frozen, validated dataclasses, with errors that name the file and the key.

:func:`build_dataclass` turns a parsed mapping (YAML, TOML) into a dataclass: every key is checked
against the fields (unknown keys are refused with the known ones), every value against its field's
type (``bool``, ``int``, ``float``, ``str``, one of them or None, or a nested dataclass given as a
mapping), and the dataclass's own validation runs; each failure is an
:class:`~rkmpc.core.errors.InputFileError` naming the file and the dotted key.
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing
from collections.abc import Mapping
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any

from rkmpc.core.errors import InputFileError, ParameterError

__all__ = ["build_dataclass", "check_keys", "check_value"]

_EXPECTED = {bool: "true or false", int: "an integer", float: "a number", str: "a non-empty string"}


def check_keys(
    data: Mapping[str, Any], known: typing.Iterable[str], path: Path, prefix: str, hint: str = ""
) -> None:
    """Refuse a key of ``data`` that is not among ``known``, naming it and the known ones."""
    names = sorted(known)
    for key in data:
        if key not in names:
            raise InputFileError(path, f"unknown key {key!r}{hint}; known: {names}", field=f"{prefix}{key}")


def build_dataclass(
    cls: type, data: Mapping[str, Any], path: Path, prefix: str = "", *, base: Any = None, hint: str = ""
) -> Any:
    """An instance of the dataclass ``cls`` from ``data``, every key checked against its fields.

    Parameters
    ----------
    cls : type
        A dataclass whose fields are ``bool``, ``int``, ``float``, ``str`` (or one of them or None)
        or nested dataclasses (given as mappings).
    data : mapping
        The parsed settings.
    path : Path
        The file they come from, for the errors.
    prefix : str
        Dotted name of the section ``data`` is (``"limits."``), for the errors.
    base : instance of ``cls``, optional
        The values of the keys ``data`` does not give (nested sections too); else the defaults.
    hint : str
        Added after ``unknown key 'x'`` in that error (where else a key may come from).

    Raises
    ------
    InputFileError
        For an unknown key, a value of the wrong type, or one the dataclass refuses; it names
        the file and the key.
    """
    hints = typing.get_type_hints(cls)
    check_keys(data, (f.name for f in fields(cls)), path, prefix, hint)
    values: dict[str, Any] = {}
    for f in fields(cls):
        if f.name not in data:
            continue
        key = f"{prefix}{f.name}"
        kind = hints[f.name]
        raw = data[f.name]
        if is_dataclass(kind):
            if raw is None:
                raw = {}
            if not isinstance(raw, Mapping):
                raise InputFileError(path, f"expected a mapping (a section), got {raw!r}", field=key)
            inner = None if base is None else getattr(base, f.name)
            values[f.name] = build_dataclass(
                typing.cast(type, kind), raw, path, f"{key}.", base=inner, hint=hint
            )
        else:
            values[f.name] = check_value(kind, raw, path, key)
    try:
        return cls(**values) if base is None else dataclasses.replace(base, **values)
    except ParameterError as exc:
        raise InputFileError(path, str(exc), field=_culprit(str(exc), cls, values, prefix)) from None


def _culprit(message: str, cls: type, values: Mapping[str, Any], prefix: str) -> str | None:
    """The dotted key a dataclass's error is about: the field it names, the one given, else the section.

    The defaults (or the base) are valid, so a section that changes one value has it at fault.
    """
    if len(values) == 1:
        return f"{prefix}{next(iter(values))}"
    for name in values:
        if re.search(rf"\b{re.escape(name)}\b", message):
            return f"{prefix}{name}"
    return prefix.rstrip(".") or None


def check_value(kind: Any, raw: Any, path: Path, key: str) -> Any:
    """``raw`` checked against the field type ``kind`` (bool, int, float, str, or one of them or None)."""
    optional = isinstance(kind, types.UnionType) and type(None) in typing.get_args(kind)
    base = next(a for a in typing.get_args(kind) if a is not type(None)) if optional else kind
    if optional and (raw is None or raw == ""):
        return None
    if base is bool and isinstance(raw, bool):
        return raw
    if base is int and isinstance(raw, int) and not isinstance(raw, bool):
        return raw
    if base is float and isinstance(raw, int | float) and not isinstance(raw, bool):
        return float(raw)
    if base is str and isinstance(raw, str) and raw:
        return raw
    expected = _EXPECTED[base]
    raise InputFileError(path, f"expected {expected}{' or null' if optional else ''}, got {raw!r}", field=key)
