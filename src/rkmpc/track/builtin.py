"""Tracks generated in code (no data file), at 1:10 scale for small cars.

Each track is described as a sequence of straights and constant-radius arcs.
The piecewise-constant curvature is smoothed with a periodic moving average
(giving linear, clothoid-like curvature transitions), heading and position are
integrated, and two designated straights are lengthened or shortened so that
the loop closes exactly.  The closed curve is then fitted with
:meth:`Path.from_points`.  ``s = 0`` lies on a straight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rkmpc.track.path import Path
from rkmpc.track.track import Track

__all__ = ["BUILTIN_DESCRIPTIONS", "builtin_track", "list_builtin_tracks"]

FloatArray = NDArray[np.float64]

# Integration step of the generator (m) and spacing of the points handed to Path.from_points (m).
_GEN_DS = 0.005
_POINT_EVERY = 40


@dataclass(frozen=True)
class _Straight:
    length: float  # m
    adjust: bool = False  # used to close the loop


@dataclass(frozen=True)
class _Arc:
    angle_deg: float  # positive = left
    radius: float  # m

    @property
    def length(self) -> float:
        return abs(math.radians(self.angle_deg)) * self.radius


_Segment = _Straight | _Arc


@dataclass(frozen=True)
class _Layout:
    segments: tuple[_Segment, ...]
    transition: float  # length of the curvature ramps (m)
    width_right: float  # m
    width_left: float  # m
    description: str


_LAYOUTS: dict[str, _Layout] = {
    "builtin": _Layout(
        segments=(
            _Straight(10.0),  # start / finish straight, heading +x
            _Arc(60.0, 8.0),  # fast left sweeper
            _Straight(3.0),
            _Arc(120.0, 3.0),  # medium left
            _Straight(6.0, adjust=True),  # back straight, heading -x
            _Arc(-35.0, 2.5),  # chicane: right-left-right
            _Arc(70.0, 2.5),
            _Arc(-35.0, 2.5),
            _Straight(3.0),
            _Arc(-90.0, 3.5),  # right-hander, now heading +y
            _Straight(4.0),
            _Arc(180.0, 1.6),  # hairpin
            _Straight(14.0, adjust=True),  # long straight heading -y
            _Arc(90.0, 5.0),  # fast left onto the main straight
            _Straight(4.0),
        ),
        transition=1.2,
        width_right=0.8,
        width_left=0.8,
        description=(
            "Club circuit at 1:10 scale (~90 m, counter-clockwise, 1.6 m wide): start/finish straight, "
            "fast left sweeper, medium left, back straight, right-left-right chicane, right-hander, "
            "1.6 m radius hairpin, long straight and a fast final left."
        ),
    ),
    "oval": _Layout(
        segments=(
            _Straight(8.0),
            _Arc(180.0, 4.0),
            _Straight(15.0, adjust=True),
            _Arc(180.0, 4.0),
            _Straight(7.0),
        ),
        transition=1.5,
        width_right=0.8,
        width_left=0.8,
        description=(
            "Oval at 1:10 scale (~55 m, counter-clockwise): two 15 m straights and two 4 m radius turns."
        ),
    ),
}

BUILTIN_DESCRIPTIONS: dict[str, str] = {name: layout.description for name, layout in _LAYOUTS.items()}
"""One-line description of each built-in track, keyed by name."""


def list_builtin_tracks() -> list[str]:
    """Names of the built-in tracks.

    Returns
    -------
    list of str
    """
    return list(_LAYOUTS)


def _integrate(
    segments: tuple[_Segment, ...], transition: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return heading (n,) and positions x, y (n+1,) on the generator grid for a layout."""
    kappa_parts = []
    for seg in segments:
        n = round(seg.length / _GEN_DS)
        # Arcs: curvature chosen so the sampled arc turns by exactly its angle.
        k = math.radians(seg.angle_deg) / (n * _GEN_DS) if isinstance(seg, _Arc) else 0.0
        kappa_parts.append(np.full(n, k))
    kappa = np.concatenate(kappa_parts)
    # Periodic moving average: linear curvature ramps of length ``transition``.
    m = max(round(transition / _GEN_DS), 1)
    kernel = np.full(m, 1.0 / m)
    padded = np.concatenate([kappa[-m:], kappa, kappa[:m]])
    smooth = np.convolve(padded, kernel, mode="same")[m:-m]
    heading = np.concatenate([[0.0], np.cumsum(smooth) * _GEN_DS])
    mid_heading = 0.5 * (heading[:-1] + heading[1:])
    x = np.concatenate([[0.0], np.cumsum(np.cos(mid_heading)) * _GEN_DS])
    y = np.concatenate([[0.0], np.cumsum(np.sin(mid_heading)) * _GEN_DS])
    return heading, x, y


def _close_layout(layout: _Layout) -> tuple[_Segment, ...]:
    """Adjust the two ``adjust`` straights so that the loop closes in position."""
    segments = list(layout.segments)
    adj = [i for i, seg in enumerate(segments) if isinstance(seg, _Straight) and seg.adjust]
    for _ in range(3):
        heading, x, y = _integrate(tuple(segments), layout.transition)
        gap = np.array([x[-1] - x[0], y[-1] - y[0]])
        if np.hypot(*gap) < 1e-9:
            break
        # Heading along each adjustable straight (at its middle).
        cols = []
        for i in adj:
            start = sum(round(seg.length / _GEN_DS) for seg in segments[:i])
            mid = start + round(segments[i].length / _GEN_DS) // 2
            cols.append([math.cos(heading[mid]), math.sin(heading[mid])])
        mat = np.array(cols).T
        delta = np.linalg.lstsq(mat, -gap, rcond=None)[0]
        for i, d in zip(adj, delta, strict=True):
            segments[i] = _Straight(segments[i].length + float(d), adjust=True)
    return tuple(segments)


def builtin_track(name: str = "builtin") -> Track:
    """Build a built-in track.

    Parameters
    ----------
    name : str, default "builtin"
        One of :func:`list_builtin_tracks`.

    Returns
    -------
    Track
        Track with constant widths and no raceline (its reference path is the
        centerline); ``s = 0`` lies on the start/finish straight.

    Raises
    ------
    ValueError
        If ``name`` is not a built-in track.
    """
    layout = _LAYOUTS.get(name)
    if layout is None:
        raise ValueError(f"unknown built-in track {name!r}; known tracks: {', '.join(_LAYOUTS)}")
    segments = _close_layout(layout)
    _, x, y = _integrate(segments, layout.transition)
    # Straight lengths are quantised to the generator step: spread the remaining
    # millimetre-sized closing gap linearly along the lap.
    frac = np.linspace(0.0, 1.0, x.size)
    x = x - frac * (x[-1] - x[0])
    y = y - frac * (y[-1] - y[0])
    pts = np.column_stack([x[:-1:_POINT_EVERY], y[:-1:_POINT_EVERY]])
    centerline = Path.from_points(pts, name=name, source="builtin")
    return Track(
        name,
        centerline,
        layout.width_right,
        layout.width_left,
        source="builtin",
    )
