"""Units of the signals a car records: the factor that turns a value in a unit into SI."""

from __future__ import annotations

import math

from rkmpc.core.errors import ParameterError

__all__ = ["UNITS", "unit_factor"]

#: Units by quantity: the factor that turns a value in the unit into SI.
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9},
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "speed": {"m/s": 1.0, "km/h": 1.0 / 3.6, "mm/s": 1e-3},
    "rate": {"rad/s": 1.0, "deg/s": math.pi / 180.0},
}


def unit_factor(quantity: str, unit: str, where: str) -> float:
    """The SI factor of ``unit`` (a :data:`UNITS` entry of ``quantity``); ParameterError naming ``where``."""
    known = UNITS[quantity]
    if unit not in known:
        raise ParameterError(f"{where} must be a {quantity} unit, one of {list(known)}; got {unit!r}")
    return known[unit]
