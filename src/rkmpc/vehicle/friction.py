"""Friction schedules: where and when the road is slippery.

A :class:`FrictionSchedule` multiplies the car's friction coefficient as a
function of time and position; plants evaluate it at the start of every
integration step. Schedules compose (:func:`combine_friction`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rkmpc.core.errors import ParameterError

__all__ = [
    "ArcPath",
    "ArcWindowFriction",
    "CircularRegion",
    "FrictionChange",
    "FrictionProduct",
    "FrictionSchedule",
    "combine_friction",
]


class _Projection(Protocol):
    @property
    def s(self) -> float: ...
    @property
    def lateral(self) -> float: ...


class ArcPath(Protocol):
    """What :class:`ArcWindowFriction` needs of a path (a :class:`rkmpc.track.path.Path`)."""

    @property
    def length(self) -> float: ...
    def position(self, s: np.ndarray) -> np.ndarray: ...
    def project(self, x: float, y: float) -> _Projection: ...


@dataclass(frozen=True)
class CircularRegion:
    """A disc of the plane where a friction change applies.

    Parameters
    ----------
    center : tuple of float
        Centre ``(x, y)`` (m).
    radius : float
        Radius (m), > 0.
    """

    center: tuple[float, float]
    radius: float

    def __post_init__(self) -> None:
        if len(self.center) != 2 or not all(math.isfinite(c) for c in self.center):
            raise ParameterError(f"CircularRegion.center must be two finite numbers, got {self.center!r}")
        if not (math.isfinite(self.radius) and self.radius > 0.0):
            raise ParameterError(f"CircularRegion.radius must be finite and > 0, got {self.radius!r}")

    def contains(self, x: float, y: float) -> bool:
        """Whether the point ``(x, y)`` (m) lies in the disc (boundary included)."""
        dx = x - self.center[0]
        dy = y - self.center[1]
        return dx * dx + dy * dy <= self.radius * self.radius


class FrictionSchedule(ABC):
    """A friction multiplier as a function of time and position.

    The plant multiplies its nominal friction coefficient by
    ``schedule(time, x, y)`` at every internal integration step.
    """

    @abstractmethod
    def __call__(self, time: float, x: float, y: float) -> float:
        """Friction multiplier (-) at ``time`` (s) and position ``(x, y)`` (m)."""


@dataclass(frozen=True)
class FrictionChange(FrictionSchedule):
    """Multiply the friction by ``factor`` during a time window, optionally only inside a region.

    Parameters
    ----------
    factor : float
        Friction multiplier (-), > 0 (e.g. 0.6 for a wet patch).
    start_time : float, optional
        Time the change begins (s), inclusive.
    end_time : float, optional
        Time the change ends (s), exclusive; ``inf`` for never.
    region : CircularRegion or None, optional
        Where it applies; everywhere when None.
    """

    factor: float
    start_time: float = 0.0
    end_time: float = math.inf
    region: CircularRegion | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.factor) and self.factor > 0.0):
            raise ParameterError(f"FrictionChange.factor must be finite and > 0, got {self.factor!r}")
        if math.isnan(self.start_time) or math.isnan(self.end_time) or self.end_time <= self.start_time:
            raise ParameterError(
                f"FrictionChange needs start_time < end_time, got {self.start_time!r}, {self.end_time!r}"
            )

    def __call__(self, time: float, x: float, y: float) -> float:
        if not self.start_time <= time < self.end_time:
            return 1.0
        if self.region is not None and not self.region.contains(x, y):
            return 1.0
        return self.factor


class ArcWindowFriction(FrictionSchedule):
    """Multiply the friction by ``factor`` over a stretch of track given by arc length.

    A point is in the stretch when its projection onto ``path`` (nearest path
    point over the whole lap) has arc length in ``[start_s, start_s + length_s)``,
    wrapping across ``s = 0``, and lies at most ``max_lateral`` from the path.
    The multiplier does not depend on time. Points outside the bounding box of
    the stretch are rejected before projecting, so the schedule costs a
    projection only near the stretch.

    Parameters
    ----------
    factor : float
        Friction multiplier (-) inside the stretch, finite and > 0.
    path : ArcPath
        The path (a :class:`rkmpc.track.path.Path`) whose arc length defines the stretch (usually the track's
        centre line).
    start_s : float
        Arc length where the stretch begins (m); wrapped into ``[0, path.length)``.
    length_s : float
        Length of the stretch along the path (m), ``0 < length_s <= path.length``.
    max_lateral : float
        Largest distance from the path (m) that still counts as on the
        stretch, finite and > 0 (e.g. twice the track's half-width).
    """

    def __init__(
        self, factor: float, path: ArcPath, start_s: float, length_s: float, max_lateral: float
    ) -> None:
        if not (math.isfinite(factor) and factor > 0.0):
            raise ParameterError(f"ArcWindowFriction.factor must be finite and > 0, got {factor!r}")
        if not math.isfinite(start_s):
            raise ParameterError(f"ArcWindowFriction.start_s must be finite, got {start_s!r}")
        if not (math.isfinite(length_s) and 0.0 < length_s <= path.length):
            raise ParameterError(
                f"ArcWindowFriction.length_s must be in (0, {path.length!r}] (the lap), got {length_s!r}"
            )
        if not (math.isfinite(max_lateral) and max_lateral > 0.0):
            raise ParameterError(f"ArcWindowFriction.max_lateral must be finite and > 0, got {max_lateral!r}")
        self.factor = float(factor)
        self.path = path
        self.start_s = float(start_s) % path.length
        self.length_s = float(length_s)
        self.max_lateral = float(max_lateral)
        # Bounding box of the stretch widened by max_lateral and by the sample spacing
        # (the path cannot leave the box of its samples by more than one spacing).
        n = min(100_000, max(100, math.ceil(self.length_s / (0.1 * self.max_lateral)) + 1))
        xy = path.position(self.start_s + np.linspace(0.0, self.length_s, n))
        pad = self.max_lateral + self.length_s / (n - 1)
        self._box = (
            float(xy[:, 0].min()) - pad,
            float(xy[:, 0].max()) + pad,
            float(xy[:, 1].min()) - pad,
            float(xy[:, 1].max()) + pad,
        )

    def contains(self, x: float, y: float) -> bool:
        """Whether the point ``(x, y)`` (m) lies on the stretch."""
        x0, x1, y0, y1 = self._box
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            return False
        proj = self.path.project(x, y)
        if abs(proj.lateral) > self.max_lateral:
            return False
        return (proj.s - self.start_s) % self.path.length < self.length_s

    def __call__(self, time: float, x: float, y: float) -> float:
        return self.factor if self.contains(x, y) else 1.0

    def __repr__(self) -> str:
        return (
            f"ArcWindowFriction(factor={self.factor!r}, start_s={self.start_s!r}, "
            f"length_s={self.length_s!r}, max_lateral={self.max_lateral!r})"
        )


@dataclass(frozen=True)
class FrictionProduct(FrictionSchedule):
    """The product of several friction schedules (each change acts on top of the others).

    Parameters
    ----------
    schedules : tuple of FrictionSchedule
        The factors, at least one.
    """

    schedules: tuple[FrictionSchedule, ...]

    def __post_init__(self) -> None:
        if not self.schedules:
            raise ParameterError("FrictionProduct needs at least one schedule")

    def __call__(self, time: float, x: float, y: float) -> float:
        factor = 1.0
        for schedule in self.schedules:
            factor *= schedule(time, x, y)
        return factor


def combine_friction(*schedules: FrictionSchedule | None) -> FrictionSchedule | None:
    """The product of the given schedules, ignoring None; None when all are None.

    A single schedule is returned as it is.
    """
    present = tuple(s for s in schedules if s is not None)
    if not present:
        return None
    if len(present) == 1:
        return present[0]
    return FrictionProduct(present)
