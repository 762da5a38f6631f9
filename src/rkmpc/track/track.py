"""Race track: a centerline with track widths and an optional raceline."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rkmpc.core.errors import ParameterError
from rkmpc.track.crossings import Crossing, bridge_problem, path_crossings
from rkmpc.track.path import Path

__all__ = ["MAX_TRACK_LENGTH", "Track", "WidthSpec", "track_length_problem"]

#: Longest track (m) rkmpc drives: 100 km, five times the longest race circuit (the Nordschleife,
#: about 21 km). A longer line has coordinates in another unit or a wrong ``--scale``, and a run on
#: it would take days of simulated time with no output.
MAX_TRACK_LENGTH = 100_000.0


#: Shortest line accepted as a track (m): far below any track a car fits on, far above a lap of
#: latitude/longitude degrees read as metres (a few hundredths of a "metre").
MIN_TRACK_LENGTH = 1.0


def track_length_problem(length: float) -> str | None:
    """Why a line ``length`` m long is no track (None when it is fine)."""
    if math.isfinite(length) and MIN_TRACK_LENGTH <= length <= MAX_TRACK_LENGTH:
        return None
    if math.isfinite(length) and length < MIN_TRACK_LENGTH:
        return (
            f"the line is {length:.4g} m long, less than {MIN_TRACK_LENGTH:g} m: coordinates in degrees "
            "(latitude, longitude) or another unit? x_m and y_m are metres"
        )
    return (
        f"the line is {length:.4g} m long, more than {MAX_TRACK_LENGTH / 1000:g} km: coordinates in "
        "another unit (mm?) or a wrong scale?"
    )


FloatArray = NDArray[np.float64]

WidthSpec = float | ArrayLike | Callable[[FloatArray], ArrayLike]
"""A track width: a constant (m), samples on a uniform arc-length grid, or a function of ``s``."""

# Samples used to validate width functions.
_WIDTH_CHECK_SAMPLES = 2000


class _PeriodicWidth:
    """Width of one side of the track as a periodic function of centerline arc length."""

    def __init__(self, spec: WidthSpec, length: float, side: str) -> None:
        self._length = length
        self._func: Callable[[FloatArray], ArrayLike] | None = None
        self._s: FloatArray = np.zeros(0)
        self._w: FloatArray = np.zeros(0)
        if callable(spec):
            self._func = spec
            check = np.asarray(
                spec(np.linspace(0.0, length, _WIDTH_CHECK_SAMPLES, endpoint=False)), dtype=float
            )
        else:
            arr = np.atleast_1d(np.asarray(spec, dtype=float))
            if arr.ndim != 1 or arr.size == 0:
                raise ParameterError(f"Track: {side} width must be a scalar or a 1-D array, got {arr.shape}")
            m = arr.size
            self._s = (np.arange(m + 1) * (length / m)).astype(np.float64)
            self._w = np.append(arr, arr[0])
            check = arr
        if not np.all(np.isfinite(check)) or np.any(check <= 0.0):
            raise ParameterError(f"Track: {side} width must be finite and > 0 everywhere")

    def __call__(self, s: ArrayLike) -> FloatArray | float:
        sw = np.mod(np.asarray(s, dtype=float), self._length)
        if self._func is not None:
            out = np.asarray(self._func(sw), dtype=float)
            out = np.broadcast_to(out, sw.shape).astype(float)
        else:
            out = np.interp(sw, self._s, self._w)
        return float(out) if out.ndim == 0 else out


class Track:
    """A closed race track.

    Parameters
    ----------
    name : str
        Track name.
    centerline : Path
        Centerline; widths and boundary queries refer to its arc length.
    width_right, width_left : float, array_like or callable
        Distance (m, > 0) from the centerline to the right / left boundary.
        A scalar is a constant width.  A 1-D array of ``m`` values gives the
        width at the uniform arc-length grid ``s_k = k * centerline.length / m``,
        ``k = 0..m-1``; it is interpolated linearly and periodically.  A callable
        maps an array of arc lengths in ``[0, length)`` (m) to widths (m).
    raceline : Path, optional
        Racing line; if given it is the :attr:`reference_path`.
    scale : float, default 1.0
        Scale factor that was applied to the source data (metadata only).
    source : str, optional
        Where the data came from (file name).
    crossings : sequence of Crossing, optional
        The centre line's crossings, when the caller has found and checked them already (the
        loaders do); found here otherwise.

    Attributes
    ----------
    crossings : tuple of Crossing
        Where the centre line crosses itself: bridges, the track passing over itself (empty for
        an ordinary circuit).  Each gives the arc lengths of the two passes; see
        :mod:`rkmpc.track.crossings` for the rule that tells a bridge from a fold.  Every
        hinted projection (the off-track check, the controllers, the lap counter) stays on the
        pass the car is on; only a first, unhinted projection of a point within a track width
        of a crossing may pick either pass, so a run should not start on a bridge.

    Raises
    ------
    ParameterError
        If a width is not finite and positive, a line is longer than :data:`MAX_TRACK_LENGTH`,
        or the centre line crosses itself anywhere but at a bridge (it folds back on itself).
    """

    def __init__(
        self,
        name: str,
        centerline: Path,
        width_right: WidthSpec,
        width_left: WidthSpec,
        *,
        raceline: Path | None = None,
        scale: float = 1.0,
        source: str | None = None,
        crossings: Sequence[Crossing] | None = None,
    ) -> None:
        if not (math.isfinite(scale) and scale > 0.0):
            raise ParameterError(f"Track: scale must be finite and > 0, got {scale!r}")
        for line in (centerline, raceline):
            problem = None if line is None else track_length_problem(line.length)
            if problem is not None:
                raise ParameterError(f"Track {name!r}: {problem}")
        self.name = name
        self.centerline = centerline
        self.raceline = raceline
        self.scale = float(scale)
        self.source = source
        self._width_specs = (width_right, width_left)
        self._wr = _PeriodicWidth(width_right, centerline.length, "right")
        self._wl = _PeriodicWidth(width_left, centerline.length, "left")
        self.crossings = tuple(self._find_crossings() if crossings is None else crossings)
        if raceline is not None:
            self._check_raceline(raceline)

    def _find_crossings(self) -> list[Crossing]:
        """The centre line's crossings; ParameterError for one that is no bridge."""
        line = self.centerline
        found = path_crossings(line)
        for c in found:
            width = max(float(self._wl(s)) + float(self._wr(s)) for s in (c.s_first, c.s_second))
            problem = bridge_problem(c.separation, c.angle, line.length, width, line.default_window)
            if problem is not None:
                raise ParameterError(
                    f"Track {self.name!r}: the centre line crosses itself at ({c.x:.3g}, {c.y:.3g}) m, "
                    f"s = {c.s_first:.4g} m and s = {c.s_second:.4g} m, and it is no bridge: {problem}"
                )
        return found

    def _check_raceline(self, raceline: Path, samples: int = 400) -> None:
        """Refuse a race line that leaves the track by more than the track's half-width.

        A race line of another track, another unit or another scale would otherwise be tracked
        as the reference, and every error measured against it, while the car is off the track.
        """
        s_hint = None
        for s in np.linspace(0.0, raceline.length, samples, endpoint=False):
            x, y = (float(v) for v in raceline.position(s))
            s_center, _, margin = self.boundary_offsets(x, y, s_hint)
            s_hint = s_center
            half = 0.5 * (float(self._wl(s_center)) + float(self._wr(s_center)))
            if margin < -half:
                where = raceline.source or "the race line"
                raise ParameterError(
                    f"Track {self.name!r}: {where} leaves the track: at s = {s:.1f} m of the race line, "
                    f"({x:.2f}, {y:.2f}) m is {-margin:.2f} m outside its boundary (the track is "
                    f"{2 * half:.2f} m wide there); a race line of another track, unit or scale?"
                )

    def width_right(self, s: ArrayLike) -> FloatArray | float:
        """Distance (m) from the centerline to the right boundary at centerline arc length ``s`` (m)."""
        return self._wr(s)

    def width_left(self, s: ArrayLike) -> FloatArray | float:
        """Distance (m) from the centerline to the left boundary at centerline arc length ``s`` (m)."""
        return self._wl(s)

    @property
    def length(self) -> float:
        """Centerline length (m)."""
        return self.centerline.length

    @property
    def reference_path(self) -> Path:
        """The raceline if present, else the centerline."""
        return self.raceline if self.raceline is not None else self.centerline

    def with_raceline(self, raceline: Path) -> Track:
        """Return a copy of this track with ``raceline`` as its racing line."""
        return Track(
            self.name,
            self.centerline,
            self._width_specs[0],
            self._width_specs[1],
            raceline=raceline,
            scale=self.scale,
            source=self.source,
            crossings=self.crossings,
        )

    def boundary_offsets(self, x: float, y: float, s_hint: float | None = None) -> tuple[float, float, float]:
        """Locate a point relative to the track boundaries.

        Parameters
        ----------
        x, y : float
            Point (m).
        s_hint : float, optional
            Centerline arc length (m) near the expected projection (see :meth:`Path.project`).

        Returns
        -------
        s_center : float
            Centerline arc length of the projection (m).
        lateral : float
            Signed offset from the centerline (m), left positive.
        margin : float
            Distance to the nearer boundary (m) measured along the normal,
            positive inside the track, negative outside.
        """
        p = self.centerline.project(x, y, s_hint=s_hint)
        wl = float(self._wl(p.s))
        wr = float(self._wr(p.s))
        margin = min(wl - p.lateral, wr + p.lateral)
        return p.s, p.lateral, margin

    def is_inside(self, x: float, y: float, s_hint: float | None = None) -> bool:
        """True when the point lies within ``[-width_right, +width_left]`` of the centerline."""
        return self.boundary_offsets(x, y, s_hint)[2] >= 0.0

    def boundaries(self, ds: float) -> tuple[FloatArray, FloatArray]:
        """Boundary polylines for plotting.

        Parameters
        ----------
        ds : float
            Spacing along the centerline (m).

        Returns
        -------
        left, right : ndarray, shape (n, 2)
            Left and right boundary points (m), not closed (first point not repeated).
        """
        smp = self.centerline.sample(ds)
        nx = -np.sin(smp.heading)
        ny = np.cos(smp.heading)
        wl = np.asarray(self._wl(smp.s), dtype=float)
        wr = np.asarray(self._wr(smp.s), dtype=float)
        left = np.column_stack([smp.x + wl * nx, smp.y + wl * ny])
        right = np.column_stack([smp.x - wr * nx, smp.y - wr * ny])
        return left, right

    def __repr__(self) -> str:
        rl = "yes" if self.raceline is not None else "no"
        return f"Track(name={self.name!r}, length={self.length:.3f}, raceline={rl}, scale={self.scale})"
