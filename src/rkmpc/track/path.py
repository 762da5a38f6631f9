"""Closed planar paths parametrised by arc length, with fast projection.

A :class:`Path` is a periodic cubic spline through a closed sequence of
points, re-parametrised so that its parameter is (to within ~1e-4 relative)
the arc length ``s`` in metres.  A dense lookup table of position, heading and
curvature supports fast, allocation-light projection of points onto the path.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from rkmpc.errors import ParameterError

__all__ = ["Path", "PathSamples", "Projection", "wrap_angle"]

FloatArray = NDArray[np.float64]

_TWO_PI = 2.0 * math.pi
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
# How often a hinted search may move its window when the nearest point lies on its edge.
_MAX_RECENTRE = 8

# Local aliases for the scalar hot path.
_PI = math.pi
_cos = math.cos
_sin = math.sin
_fmod = math.fmod
_subtract = np.subtract
_multiply = np.multiply
_add = np.add
_new_object = object.__new__


def wrap_angle(angle: ArrayLike) -> FloatArray | float:
    """Wrap angles into the interval (-pi, pi].

    Parameters
    ----------
    angle : float or array_like
        Angle(s) in rad, any shape.

    Returns
    -------
    float or ndarray
        Wrapped angle(s) in rad, same shape as the input (a float for scalar input).
    """
    a = np.asarray(angle, dtype=float)
    w = np.pi - np.mod(np.pi - a, _TWO_PI)
    if w.ndim == 0:
        return float(w)
    return w


def _wrap_scalar(a: float) -> float:
    w = math.pi - math.fmod(math.pi - a, _TWO_PI)
    if w <= -math.pi:
        w += _TWO_PI
    elif w > math.pi:
        w -= _TWO_PI
    return w


@dataclass(frozen=True)
class Projection:
    """Result of projecting a point onto a :class:`Path`.

    Parameters
    ----------
    s : float
        Arc length of the nearest path point (m), in ``[0, length)``.
    lateral : float
        Signed distance from the path (m), positive to the left of the path direction.
    heading : float
        Path heading at ``s`` (rad), wrapped to (-pi, pi].
    """

    s: float
    lateral: float
    heading: float


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
        self._tab_ds = self.length / n_tab
        self._n_tab = n_tab
        s_tab = np.arange(n_tab + 1) * self._tab_ds
        pos = spline(s_tab)
        d1 = self._d1(s_tab)
        d2 = self._d2(s_tab)
        head = np.arctan2(d1[:, 1], d1[:, 0])
        curv = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.hypot(d1[:, 0], d1[:, 1]) ** 3
        unwrapped = np.unwrap(head)
        self.winding_number = round((unwrapped[-1] - unwrapped[0]) / _TWO_PI)
        # Close the unwrapped table exactly so interpolation is consistent at s = L.
        self._tab_s = s_tab
        self._tab_x = pos[:-1, 0].copy()
        self._tab_y = pos[:-1, 1].copy()
        self._tab_head = head[:-1].copy()
        self._tab_curv = curv[:-1].copy()
        self._tab_unwrapped = unwrapped
        self._tab_xy = pos[:-1].copy()
        # Plain Python lists for the scalar hot path (cheaper element access).
        self._lx = self._tab_x.tolist()
        self._ly = self._tab_y.tolist()
        self._lh = self._tab_head.tolist()
        self._lk = self._tab_curv.tolist()

        window = max(10.0 * mean_spacing, 100.0 * self._tab_ds)
        self.default_window = float(min(self.length / 8.0, window))
        self._pad = math.ceil(self.default_window / self._tab_ds) + 2
        pad = self._pad
        self._pad_x = np.concatenate([self._tab_x[-pad:], self._tab_x, self._tab_x[:pad]])
        self._pad_y = np.concatenate([self._tab_y[-pad:], self._tab_y, self._tab_y[:pad]])
        self._tree: cKDTree | None = None
        # Hot-path constants: padded table as one (2, n + 2 pad) array (rows x, y), the
        # search half-width of the default window, and per table point the tuple
        # (x, y, heading, curvature, cos(heading), sin(heading)) for the refinement.
        self._pad_xy = np.ascontiguousarray(np.vstack([self._pad_x, self._pad_y]))
        self._default_half = max(math.ceil(self.default_window / self._tab_ds), 2)
        self._lrow = [
            (xi, yi, th, k, math.cos(th), math.sin(th))
            for xi, yi, th, k in zip(self._lx, self._ly, self._lh, self._lk, strict=True)
        ]
        # Scratch buffers of the hinted search, per thread (see _search_buffers).
        self._buffers: dict[tuple[int, int], tuple[Any, ...]] = {}

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_buffers"] = {}  # scratch space: neither pickled nor shared between copies
        return state

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
        """Path heading (rad), wrapped to (-pi, pi].

        Parameters
        ----------
        s : float or array_like, shape (...)
            Arc length (m).

        Returns
        -------
        float or ndarray, shape (...)
            Heading angle of the tangent, measured from the x axis.
        """
        d = np.asarray(self._d1(self._wrap_s(s)), dtype=float)
        h = np.arctan2(d[..., 1], d[..., 0])
        h = np.where(h <= -np.pi, h + _TWO_PI, h)
        return float(h) if h.ndim == 0 else h

    def heading_unwrapped(self, s: ArrayLike) -> FloatArray | float:
        """Heading (rad) as a continuous function of arc length.

        For ``s`` in ``[0, length)`` this is the continuous heading starting
        from ``heading(0)``; each further lap adds ``2 * pi * winding_number``.

        Parameters
        ----------
        s : float or array_like, shape (...)
            Arc length (m), any real value.

        Returns
        -------
        float or ndarray, shape (...)
        """
        s_arr = np.asarray(s, dtype=float)
        laps = np.floor(s_arr / self.length)
        sm = s_arr - laps * self.length
        local = np.asarray(self.heading(sm), dtype=float)
        approx = np.interp(sm, self._tab_s, self._tab_unwrapped)
        out = local + _TWO_PI * np.round((approx - local) / _TWO_PI) + _TWO_PI * self.winding_number * laps
        return float(out) if out.ndim == 0 else out

    def curvature(self, s: ArrayLike) -> FloatArray | float:
        """Signed curvature (1/m), positive for left turns.

        Parameters
        ----------
        s : float or array_like, shape (...)
            Arc length (m).

        Returns
        -------
        float or ndarray, shape (...)
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
    def _refine(self, i: int, x: float, y: float) -> Projection:
        """Refine a projection starting from dense-table point ``i`` (scalar hot path)."""
        xi, yi, th, k, c, sn = self._lrow[i]
        ds = self._tab_ds
        dx = x - xi
        dy = y - yi
        along = dx * c + dy * sn
        lat = dy * c - dx * sn
        den = 1.0 - k * lat
        if 0.1 > den:
            den = 0.1
        d = along / den
        if -ds > d:
            d = -ds
        if ds < d:
            d = ds
        # Second step on the local second-order (clothoid-free) expansion.
        th_d = th + k * d
        half = 0.5 * k * d * d
        px = xi + c * d - half * sn
        py = yi + sn * d + half * c
        cd = _cos(th_d)
        sd = _sin(th_d)
        ex = x - px
        ey = y - py
        along = ex * cd + ey * sd
        lat = ey * cd - ex * sd
        den = 1.0 - k * lat
        if 0.1 > den:
            den = 0.1
        d += along / den
        if -ds > d:
            d = -ds
        if ds < d:
            d = ds
        th_d = th + k * d
        half = 0.5 * k * d * d
        px = xi + c * d - half * sn
        py = yi + sn * d + half * c
        cd = _cos(th_d)
        sd = _sin(th_d)
        lat = (y - py) * cd - (x - px) * sd
        length = self.length
        s = i * ds + d
        if s < 0.0:
            s += length
        elif s >= length:
            s -= length
        if s >= length:  # guards the rounding case s == length
            s = 0.0
        # Heading wrapped into (-pi, pi] (inlined _wrap_scalar).
        w = _PI - _fmod(_PI - th_d, _TWO_PI)
        if w <= -_PI:
            w += _TWO_PI
        elif w > _PI:
            w -= _TWO_PI
        # Projection(s, lat, w) without the frozen dataclass's per-field __setattr__.
        proj = _new_object(Projection)
        attrs = proj.__dict__
        attrs["s"] = s
        attrs["lateral"] = lat
        attrs["heading"] = w
        return proj

    def _nearest_global(self, xy: FloatArray) -> NDArray[np.intp]:
        if self._tree is None:
            self._tree = cKDTree(self._tab_xy)
        _, idx = self._tree.query(xy)
        return np.asarray(idx, dtype=np.intp)

    def _search_buffers(self, half: int) -> tuple[Any, ...]:
        """Scratch arrays of a hinted search of half-width ``half``, owned by the calling thread."""
        key = (threading.get_ident(), half)
        bufs = self._buffers.get(key)
        if bufs is None:
            m = 2 * half + 1
            q = np.empty((2, 1))
            diff = np.empty((2, m))
            dist = np.empty(m)
            bufs = (q, diff, diff[0], diff[1], dist)
            self._buffers[key] = bufs
        return bufs

    def _nearest_hinted(self, x: float, y: float, s_hint: float, window: float) -> int:
        n = self._n_tab
        ds = self._tab_ds
        half = math.ceil(window / ds)
        half = max(half, 2)
        centre = round((s_hint % self.length) / ds) % n
        pad = self._pad
        if half + 1 <= pad:
            return self._search_padded(x, y, centre, half)
        best = centre
        for _ in range(_MAX_RECENTRE):
            lo = centre - half
            hi = centre + half + 1
            idx = np.arange(lo, hi) % n
            xs = self._tab_x[idx]
            ys = self._tab_y[idx]
            ddx = xs - x
            ddy = ys - y
            j = int(np.argmin(ddx * ddx + ddy * ddy))
            best = (lo + j) % n
            if 0 < j < hi - lo - 1 or 2 * half + 1 >= n:
                break
            centre = best
        return best

    def _search_padded(self, x: float, y: float, centre: int, half: int) -> int:
        """Hinted nearest-table-point search in the padded table (window within the padding).

        The same arithmetic as the plain search (``(x_i - x)**2 + (y_i - y)**2``,
        first minimum), in preallocated buffers.
        """
        key = (threading.get_ident(), half)
        bufs = self._buffers.get(key)
        if bufs is None:
            bufs = self._search_buffers(half)
        q, diff, dx2, dy2, dist = bufs
        q[0, 0] = x
        q[1, 0] = y
        n = self._n_tab
        m = 2 * half + 1
        last = m - 1
        first = self._pad - half
        pad_xy = self._pad_xy
        best = centre
        for _ in range(_MAX_RECENTRE):
            a = centre + first
            _subtract(pad_xy[:, a : a + m], q, out=diff)
            _multiply(diff, diff, out=diff)
            _add(dx2, dy2, out=dist)
            j = int(dist.argmin())
            best = (centre - half + j) % n
            if 0 < j < last or m >= n:
                break
            centre = best
        return best

    def _project_hinted(self, x: float, y: float, s_hint: float) -> Projection:
        """Hinted projection with the default window; no argument checks (hot path)."""
        ds = self._tab_ds
        n = self._n_tab
        centre = round((s_hint % self.length) / ds) % n
        i = self._search_padded(x, y, centre, self._default_half)
        return self._refine(i, x, y)

    def project(
        self,
        x: float,
        y: float,
        s_hint: float | None = None,
        window: float | None = None,
    ) -> Projection:
        """Project a point onto the path (nearest path point).

        Without a hint the nearest point over the whole lap is found (KD-tree on
        the dense table, then local Newton refinement).  With ``s_hint`` only
        path points within ``+-window`` (m of arc length) of the hint are
        searched, so the result cannot jump to a neighbouring part of the track;
        if the nearest point lies on the edge of the window, the window is moved
        along the path (a few times at most) so the search follows the path
        continuously.  The window wraps across ``s = 0``.

        Parameters
        ----------
        x, y : float
            Point (m).
        s_hint : float, optional
            Arc length (m) near which the projection is expected (e.g. the
            previous one).  Any real value; wrapped modulo the length.
        window : float, optional
            Half-width of the search window (m); defaults to :attr:`default_window`.

        Returns
        -------
        Projection
            ``s`` in ``[0, length)``, signed lateral offset (left positive) and heading.
        """
        x = float(x)
        y = float(y)
        if s_hint is None:
            i = int(self._nearest_global(np.array([x, y]))[()])
        elif window is None:
            return self._project_hinted(x, y, float(s_hint))
        else:
            w = float(window)
            if not (w > 0.0):
                raise ParameterError(f"Path.project: window must be > 0, got {window!r}")
            i = self._nearest_hinted(x, y, float(s_hint), w)
        return self._refine(i, x, y)

    def project_many(self, xy: ArrayLike, *, hinted: bool = True) -> tuple[FloatArray, FloatArray]:
        """Project many points.

        Parameters
        ----------
        xy : array_like, shape (n, 2)
            Points (m).
        hinted : bool, default True
            If True the points are taken as a trajectory in driving order: the
            first is projected globally and each following one with the
            previous result as hint (continuous across the start line).  If
            False each point is projected globally and independently.

        Returns
        -------
        s : ndarray, shape (n,)
            Arc length (m) in ``[0, length)``.
        lateral : ndarray, shape (n,)
            Signed lateral offset (m), left positive.
        """
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        n = pts.shape[0]
        s_out = np.empty(n)
        lat_out = np.empty(n)
        if n == 0:
            return s_out, lat_out
        if hinted:
            hint: float | None = None
            for k, (px, py) in enumerate(pts.tolist()):
                p = self.project(px, py, s_hint=hint)
                s_out[k] = p.s
                lat_out[k] = p.lateral
                hint = p.s
        else:
            idx = self._nearest_global(pts).tolist()
            for k, (px, py) in enumerate(pts.tolist()):
                p = self._refine(idx[k], px, py)
                s_out[k] = p.s
                lat_out[k] = p.lateral
        return s_out, lat_out

    def __repr__(self) -> str:
        return f"Path(name={self.name!r}, length={self.length:.3f})"


def dedupe_closed(pts: FloatArray) -> FloatArray:
    """Drop consecutive exact duplicate points, including a closing copy of the first.

    Parameters
    ----------
    pts : ndarray, shape (n, 2)
        Points (m).

    Returns
    -------
    ndarray, shape (m, 2)
        The points with duplicates removed, ``m <= n``.
    """
    return pts[dedupe_mask(pts)]


def dedupe_mask(pts: FloatArray) -> NDArray[np.bool_]:
    """Boolean mask of the points kept by :func:`dedupe_closed`, shape ``(n,)``."""
    if pts.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    keep = np.ones(pts.shape[0], dtype=bool)
    keep[1:] = np.any(pts[1:] != pts[:-1], axis=1)
    kept = np.flatnonzero(keep)
    # Drop trailing points equal to the first point (a repeated closing point).
    for j in kept[::-1]:
        if j == 0 or np.any(pts[j] != pts[0]):
            break
        keep[j] = False
    return keep
