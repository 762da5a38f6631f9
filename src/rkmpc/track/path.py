"""Closed planar paths parametrised by arc length.

A :class:`Path` is a periodic cubic spline through a closed sequence of
points, re-parametrised so that its parameter is (to within ~1e-4 relative)
the arc length ``s`` in metres.  It evaluates position, heading and curvature,
and projects points onto itself through a
:class:`~rkmpc.track.projection.PathProjector` built from a dense lookup table
of position, heading and curvature (see :mod:`rkmpc.track.projection`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from rkmpc.core.angles import TWO_PI as _TWO_PI
from rkmpc.core.errors import ParameterError
from rkmpc.track.points import dedupe_closed
from rkmpc.track.projection import PathProjector, Projection

__all__ = ["Path", "PathSamples", "Projection"]

FloatArray = NDArray[np.float64]

# Gauss-Legendre nodes/weights on [-1, 1] used for arc-length quadrature.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(5)
# Sub-intervals per spline segment when tabulating arc length against the parameter.
_ARC_SUBDIV = 8
# Number of re-parametrisation passes (chord length -> arc length).
_REPARAM_PASSES = 2
# Knots of the arc-length spline per input point.
_KNOT_FACTOR = 6
# Target spacing of the dense lookup table (m) and bounds on its size.
_TABLE_SPACING = 0.02
_TABLE_MIN = 2000
_TABLE_MAX = 20000


@dataclass(frozen=True)
class PathSamples:
    """Samples of a path on a uniform arc-length grid covering one lap.

    All arrays have shape ``(n,)``; ``s[0] == 0`` and ``s[-1] < length`` (the
    closing point is not repeated).

    Parameters
    ----------
    s : ndarray
        Arc length (m).
    x, y : ndarray
        Position (m).
    heading : ndarray
        Heading (rad), wrapped to (-pi, pi].
    curvature : ndarray
        Curvature (1/m), positive for left turns.
    """

    s: FloatArray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    curvature: FloatArray

    @property
    def xy(self) -> FloatArray:
        """Positions stacked as an ``(n, 2)`` array (m)."""
        return np.column_stack([self.x, self.y])

    @property
    def ds(self) -> float:
        """Grid spacing (m)."""
        return float(self.s[1] - self.s[0]) if self.s.size > 1 else 0.0


def _arc_length_table(spline: CubicSpline) -> tuple[FloatArray, FloatArray]:
    """Tabulate arc length against the spline parameter.

    Returns the parameter values ``u`` (m,) and cumulative arc length ``s`` (m,)
    on a grid that subdivides each spline segment into ``_ARC_SUBDIV`` parts.
    """
    knots = spline.x
    frac = np.linspace(0.0, 1.0, _ARC_SUBDIV + 1)[:-1]
    u = (knots[:-1, None] + np.diff(knots)[:, None] * frac[None, :]).ravel()
    u = np.append(u, knots[-1])
    h = np.diff(u)
    mid = 0.5 * (u[:-1] + u[1:])
    nodes = mid[:, None] + 0.5 * h[:, None] * _GL_NODES[None, :]
    deriv = spline(nodes, 1)  # (m, 5, 2)
    speed = np.hypot(deriv[..., 0], deriv[..., 1])
    pieces = 0.5 * h * (speed @ _GL_WEIGHTS)
    s = np.concatenate([[0.0], np.cumsum(pieces)])
    return u, s


class Path:
    """Closed (periodic) planar curve parametrised by arc length.

    Build one with :meth:`from_points`.  All evaluation methods accept any real
    arc length ``s`` (m); values outside ``[0, length)`` wrap around the lap.

    Attributes
    ----------
    name : str
        Free-form name.
    source : str or None
        Where the points came from (e.g. a file name), for messages.
    length : float
        Length of one lap (m).
    winding_number : int
        Net number of turns of the heading over one lap (+1 for a
        counter-clockwise loop, -1 for clockwise).
    default_window : float
        Half-width (m) of the arc-length window searched by a hinted
        :meth:`project` when no ``window`` is given:
        ``min(length / 8, max(10 * mean input point spacing, 100 * table spacing))``.
    knot_s : ndarray
        Arc length (m) of each (de-duplicated) input point, shape ``(n,)``.
    projector : PathProjector
        Projection onto the path's dense table (spacing about 2 cm, 2000 to
        20000 points); :meth:`project` and :meth:`project_many` delegate to it.
        Safe to share between threads.
    """

    def __init__(
        self,
        spline: CubicSpline,
        *,
        knot_s: FloatArray,
        mean_spacing: float,
        name: str = "",
        source: str | None = None,
    ) -> None:
        self._spline = spline
        self.name = name
        self.source = source
        self.length = float(spline.x[-1] - spline.x[0])
        self.knot_s = knot_s
        self._d1 = spline.derivative(1)
        self._d2 = spline.derivative(2)

        n_tab = int(np.clip(math.ceil(self.length / _TABLE_SPACING), _TABLE_MIN, _TABLE_MAX))
        tab_ds = self.length / n_tab
        s_tab = np.arange(n_tab + 1) * tab_ds
        pos = spline(s_tab)
        d1 = self._d1(s_tab)
        d2 = self._d2(s_tab)
        head = np.arctan2(d1[:, 1], d1[:, 0])
        curv = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.hypot(d1[:, 0], d1[:, 1]) ** 3
        unwrapped = np.unwrap(head)
        self.winding_number = round((unwrapped[-1] - unwrapped[0]) / _TWO_PI)
        # The unwrapped heading table includes the closing point s = L, so that
        # interpolation is consistent up to the end of the lap.
        self._tab_s = s_tab
        self._tab_unwrapped = unwrapped

        window = max(10.0 * mean_spacing, 100.0 * tab_ds)
        self.default_window = float(min(self.length / 8.0, window))
        # The dense table without the closing point, for projection.
        self.projector = PathProjector(
            pos[:-1, 0],
            pos[:-1, 1],
            head[:-1],
            curv[:-1],
            ds=tab_ds,
            length=self.length,
            default_window=self.default_window,
        )

    def __getstate__(self) -> dict[str, Any]:
        # The projector drops its per-thread scratch buffers itself when pickled.
        return self.__dict__.copy()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_points(cls, xy: ArrayLike, *, name: str = "", source: str | None = None) -> Path:
        """Fit a closed arc-length-parametrised spline through points.

        Parameters
        ----------
        xy : array_like, shape (n, 2)
            Points in order along the loop (m).  The loop is closed implicitly;
            consecutive exact duplicates, and a last point equal to the first,
            are dropped.
        name : str, optional
            Name of the path.
        source : str, optional
            Origin of the points (file name), for messages.

        Returns
        -------
        Path
            The fitted path; ``s = 0`` at the first input point.

        Raises
        ------
        ParameterError
            If ``xy`` is not an ``(n, 2)`` finite array with at least 4 distinct points.
        """
        pts = np.asarray(xy, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ParameterError(f"Path.from_points: xy must have shape (n, 2), got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise ParameterError("Path.from_points: xy contains NaN or inf")
        pts = dedupe_closed(pts)
        if pts.shape[0] < 4:
            raise ParameterError(f"Path.from_points: need at least 4 distinct points, got {pts.shape[0]}")

        closed = np.vstack([pts, pts[:1]])
        chord = np.hypot(*np.diff(closed, axis=0).T)
        mean_spacing = float(chord.mean())
        u = np.concatenate([[0.0], np.cumsum(chord)])
        spline = CubicSpline(u, closed, bc_type="periodic")

        # Arc length of the input points on the first (chord-length) spline.
        u_tab, s_tab = _arc_length_table(spline)
        knot_s = np.interp(u[:-1], u_tab, s_tab)
        first_length = float(s_tab[-1])

        n_knots = max(_KNOT_FACTOR * pts.shape[0], 16)
        for _ in range(_REPARAM_PASSES):
            u_tab, s_tab = _arc_length_table(spline)
            total = float(s_tab[-1])
            s_new = np.linspace(0.0, total, n_knots + 1)
            u_new = np.interp(s_new, s_tab, u_tab)
            new_pts = spline(u_new)
            new_pts[-1] = new_pts[0]
            spline = CubicSpline(s_new, new_pts, bc_type="periodic")

        length = float(spline.x[-1])
        knot_s = knot_s * (length / first_length)
        return cls(spline, knot_s=knot_s, mean_spacing=mean_spacing, name=name, source=source)

    # ------------------------------------------------------------------ evaluation
    def _wrap_s(self, s: ArrayLike) -> FloatArray:
        return np.mod(np.asarray(s, dtype=float), self.length)

    def position(self, s: ArrayLike) -> FloatArray:
        """Position on the path.

        Parameters
        ----------
        s : float or array_like, shape (...)
            Arc length (m), wrapped modulo :attr:`length`.

        Returns
        -------
        ndarray, shape (..., 2)
            ``(x, y)`` in m.
        """
        return np.asarray(self._spline(self._wrap_s(s)), dtype=float)

    def tangent(self, s: ArrayLike) -> FloatArray:
        """Unit tangent vector(s), shape ``(..., 2)``, at arc length ``s`` (m)."""
        d = np.asarray(self._d1(self._wrap_s(s)), dtype=float)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def heading(self, s: ArrayLike) -> FloatArray | float:
        """Heading (rad) of the tangent from the x axis, wrapped to (-pi, pi], at arc length ``s`` (m).

        A float for a scalar ``s``, else an array of its shape.
        """
        d = np.asarray(self._d1(self._wrap_s(s)), dtype=float)
        h = np.arctan2(d[..., 1], d[..., 0])
        h = np.where(h <= -np.pi, h + _TWO_PI, h)
        return float(h) if h.ndim == 0 else h

    def heading_unwrapped(self, s: ArrayLike) -> FloatArray | float:
        """Heading (rad) as a continuous function of arc length ``s`` (m, any real value).

        For ``s`` in ``[0, length)`` this is the continuous heading starting
        from ``heading(0)``; each further lap adds ``2 * pi * winding_number``.
        A float for a scalar ``s``, else an array of its shape.
        """
        s_arr = np.asarray(s, dtype=float)
        laps = np.floor(s_arr / self.length)
        sm = s_arr - laps * self.length
        local = np.asarray(self.heading(sm), dtype=float)
        approx = np.interp(sm, self._tab_s, self._tab_unwrapped)
        out = local + _TWO_PI * np.round((approx - local) / _TWO_PI) + _TWO_PI * self.winding_number * laps
        return float(out) if out.ndim == 0 else out

    def curvature(self, s: ArrayLike) -> FloatArray | float:
        """Signed curvature (1/m), positive for left turns, at arc length ``s`` (m).

        A float for a scalar ``s``, else an array of its shape.
        """
        sw = self._wrap_s(s)
        d1 = np.asarray(self._d1(sw), dtype=float)
        d2 = np.asarray(self._d2(sw), dtype=float)
        num = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
        k = num / np.hypot(d1[..., 0], d1[..., 1]) ** 3
        return float(k) if k.ndim == 0 else k

    def speed_error(self, n: int = 20000) -> float:
        """Largest deviation of ``|d(x, y)/ds|`` from 1 over ``n`` samples (-)."""
        s = np.linspace(0.0, self.length, n, endpoint=False)
        d = np.asarray(self._d1(s), dtype=float)
        return float(np.max(np.abs(np.hypot(d[:, 0], d[:, 1]) - 1.0)))

    def sample(self, ds: float) -> PathSamples:
        """Sample the path on a uniform grid over one lap.

        Parameters
        ----------
        ds : float
            Requested spacing (m); the actual spacing is ``length / ceil(length / ds)``.

        Returns
        -------
        PathSamples
            Arrays of shape ``(n,)`` with ``n = ceil(length / ds)``.
        """
        if not (math.isfinite(ds) and ds > 0.0):
            raise ParameterError(f"Path.sample: ds must be finite and > 0, got {ds!r}")
        n = max(math.ceil(self.length / ds - 1e-9), 4)
        s = (np.arange(n) * (self.length / n)).astype(np.float64)
        pos = self.position(s)
        return PathSamples(
            s=s,
            x=pos[:, 0].copy(),
            y=pos[:, 1].copy(),
            heading=np.asarray(self.heading(s), dtype=float),
            curvature=np.asarray(self.curvature(s), dtype=float),
        )

    # ------------------------------------------------------------------ projection
    def project(
        self, x: float, y: float, s_hint: float | None = None, window: float | None = None
    ) -> Projection:
        """Nearest path point to ``(x, y)`` (m); see :meth:`PathProjector.project`.

        Without ``s_hint`` (m, any real value) the nearest point over the whole lap is found; with
        it only path points within ``+-window`` (m, default :attr:`default_window`) of the hint, the
        window following the path (across ``s = 0``).  The :class:`Projection` holds ``s`` (m) in
        ``[0, length)``, the signed lateral offset (m, left positive) and the heading (rad).
        """
        return self.projector.project(x, y, s_hint, window)

    def project_many(self, xy: ArrayLike, *, hinted: bool = True) -> tuple[FloatArray, FloatArray]:
        """Project many points ``xy`` (m), shape ``(n, 2)``; see :meth:`PathProjector.project_many`.

        With ``hinted`` the points are a trajectory in driving order, each hinted by the previous
        projection (the first projected globally); without, all are projected globally.  Returns
        ``(s, lateral)``, shape ``(n,)`` each: arc length (m) in ``[0, length)`` and signed lateral
        offset (m), left positive.
        """
        return self.projector.project_many(xy, hinted=hinted)

    def __repr__(self) -> str:
        return f"Path(name={self.name!r}, length={self.length:.3f})"
