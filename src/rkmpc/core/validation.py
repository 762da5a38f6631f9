"""Checks shared by the validated settings (frozen dataclasses) of the whole package.

The predicates (:func:`is_integer`, :func:`is_positive_number`) say whether a
value passes; the ``require_*`` functions raise :class:`ParameterError` naming
the class and the attribute that failed.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection
from typing import Any

from rkmpc.core.errors import ParameterError

__all__ = [
    "is_finite_real",
    "is_integer",
    "is_positive_number",
    "is_real",
    "named_numbers",
    "require_bool",
    "require_choice",
    "require_nonnegative",
    "require_positive",
    "require_positive_or_none",
    "require_positive_value",
]


def is_integer(value: Any, minimum: int | None = None) -> bool:
    """An integer (Python or numpy, not a bool), at least ``minimum`` when given."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        return False
    return minimum is None or int(value) >= minimum


def is_real(value: Any) -> bool:
    """A real number (Python or numpy, not a bool); NaN and the infinities count."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_finite_real(value: Any) -> bool:
    """Whether ``value`` is a finite real number: :func:`is_real` without NaN and the infinities.

    Parameters
    ----------
    value : Any
        The value to test, in any unit.

    Returns
    -------
    bool
        True for a finite Python or numpy real number (int, float, ``numpy.float32``...); False
        for a bool, NaN, an infinity or anything that is not a real number.
    """
    return is_real(value) and math.isfinite(value)


def is_positive_number(value: Any, upper: float = math.inf) -> bool:
    """A finite real number (not a bool) in ``(0, upper]``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return False
    f = float(value)
    return math.isfinite(f) and 0.0 < f <= upper


def require_bool(obj: object, *names: str) -> None:
    """Raise :class:`ParameterError` unless each named attribute is ``True`` or ``False``."""
    for name in names:
        value = getattr(obj, name)
        if not isinstance(value, bool):
            raise ParameterError(f"{type(obj).__name__}.{name} must be true or false, got {value!r}")


def require_choice(obj: object, name: str, allowed: Collection[Any]) -> None:
    """Raise :class:`ParameterError` unless the attribute ``name`` of ``obj`` is one of ``allowed``.

    Parameters
    ----------
    obj : object
        The object checked (a settings dataclass); its class is named in the error.
    name : str
        The attribute to check.
    allowed : collection
        The values the attribute may take (names, usually strings; ``None`` where leaving it
        unset is allowed), compared with ``in``. The error lists them in their order.

    Raises
    ------
    ParameterError
        ``ClassName.name must be one of [...], got value`` for any other value.
    """
    value = getattr(obj, name)
    if value not in allowed:
        raise ParameterError(f"{type(obj).__name__}.{name} must be one of {list(allowed)}, got {value!r}")


def require_nonnegative(obj: object, *names: str) -> None:
    """Raise :class:`ParameterError` unless each named attribute is finite and >= 0."""
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value >= 0):
            raise ParameterError(f"{type(obj).__name__}.{name} must be finite and >= 0, got {value}")


def require_positive(obj: object, *names: str) -> None:
    """Raise :class:`ParameterError` unless each named attribute is a finite real number > 0."""
    for name in names:
        value = getattr(obj, name)
        if not is_positive_number(value):
            raise ParameterError(f"{type(obj).__name__}.{name} must be finite and > 0, got {value!r}")


def require_positive_or_none(obj: object, *names: str) -> None:
    """Raise :class:`ParameterError` unless each named attribute is None or finite and > 0.

    :func:`require_positive` that lets ``None`` (a setting left unset) through.

    Parameters
    ----------
    obj : object
        The object checked (a settings dataclass); its class is named in the error.
    *names : str
        The attributes to check, in order; each a number in its own unit (s, Hz, m...) or None.

    Raises
    ------
    ParameterError
        ``ClassName.name must be finite and > 0, got value`` for the first attribute that is
        neither None nor a finite number > 0.
    """
    require_positive(obj, *(name for name in names if getattr(obj, name) is not None))


def require_positive_value(value: Any, name: str) -> float:
    """``value`` as a float when it is a finite number > 0; else :class:`ParameterError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a number, got {value!r}")
    out = float(value)
    if not (math.isfinite(out) and out > 0.0):
        raise ParameterError(f"{name} must be finite and > 0, got {value!r}")
    return out


def named_numbers(value: Any, name: str) -> tuple[tuple[str, float], ...]:
    """``value`` as a tuple of ``(label, number)`` pairs; else :class:`ParameterError` naming ``name``.

    ``value`` is a sequence (a tuple, or a JSON list) of ``[str, number or None]`` pairs; None is
    read as NaN (JSON has no NaN). The numbers keep their units.
    """
    problem = f"{name} must be a sequence of [name, number or None] pairs, got {value!r}"
    if not isinstance(value, (tuple, list)):
        raise ParameterError(problem)
    out = []
    for pair in value:
        if not isinstance(pair, (tuple, list)) or len(pair) != 2 or not isinstance(pair[0], str):
            raise ParameterError(problem)
        number = math.nan if pair[1] is None else pair[1]
        if not is_real(number):
            raise ParameterError(problem)
        out.append((pair[0], float(number)))
    return tuple(out)
