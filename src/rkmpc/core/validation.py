"""Checks shared by the validated parameter dataclasses."""

from __future__ import annotations

import math

from rkmpc.core.errors import ParameterError


def require_nonnegative(obj: object, *names: str) -> None:
    """Raise :class:`ParameterError` unless each named attribute is finite and >= 0."""
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value >= 0):
            raise ParameterError(f"{type(obj).__name__}.{name} must be finite and >= 0, got {value}")


def require_positive(obj: object, *names: str) -> None:
    """Raise :class:`ParameterError` unless each named attribute is finite and > 0."""
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{type(obj).__name__}.{name} must be finite and > 0, got {value}")
