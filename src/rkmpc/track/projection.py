"""Fast projection of points onto a closed path tabulated on a uniform arc-length grid.

A :class:`PathProjector` owns everything needed to find the nearest point of a
closed path to a query point: the dense table of positions, headings and
curvatures, a padded copy of it for window searches that cross ``s = 0``, a
KD-tree for global searches, per-thread scratch buffers and a two-step local
Newton refinement.  :class:`rkmpc.track.path.Path` builds one from its spline
and delegates :meth:`~rkmpc.track.path.Path.project` to it. The tests compare
it against a slow, plain implementation of the same projection
(``tests/projection_reference.py``).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from rkmpc.core.angles import wrap_scalar
from rkmpc.core.errors import ParameterError

__all__ = ["MAX_RECENTRE", "PathProjector", "Projection"]

FloatArray = NDArray[np.float64]

#: How often a hinted search may move its window when the nearest point lies on its edge.
MAX_RECENTRE = 8

# Local aliases for the scalar hot path.
_cos = math.cos
_sin = math.sin
_subtract = np.subtract
_multiply = np.multiply
_add = np.add
_new_object = object.__new__


def _newton_offset(dx: float, dy: float, c: float, sn: float, k: float) -> float:
    """Newton step (m) along a path point of heading cos ``c``, sin ``sn`` and curvature ``k`` (1/m).

    ``(dx, dy)`` (m) is the query point relative to the path point.
    """
    along = dx * c + dy * sn
    lat = dy * c - dx * sn
    den = 1.0 - k * lat
    if 0.1 > den:
        den = 0.1
    return along / den


def _local_point(
    d: float, ds: float, xi: float, yi: float, th: float, k: float, c: float, sn: float
) -> tuple[float, float, float, float, float, float]:
    """Clamp the offset ``d`` (m) to ``[-ds, ds]`` and evaluate the local second-order expansion there.

    ``(xi, yi)`` (m), ``th`` (rad), ``k`` (1/m), ``c`` and ``sn`` (cos and sin of ``th``) describe
    the table point.  Returns ``(d, heading, x, y, cos(heading), sin(heading))``, in m and rad.
    """
    if -ds > d:
        d = -ds
    if ds < d:
        d = ds
    th_d = th + k * d
    half = 0.5 * k * d * d
    px = xi + c * d - half * sn
    py = yi + sn * d + half * c
    return d, th_d, px, py, _cos(th_d), _sin(th_d)


@dataclass(frozen=True)
class Projection:
    """Result of projecting a point onto a path.

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


class PathProjector:
    """Nearest-point projection onto a closed path given by a dense arc-length table.

    Table point ``i`` lies at arc length ``i * ds``; the table covers one lap
    without repeating the closing point, so ``n * ds == length``.

    Parameters
    ----------
    x, y : array_like, shape (n,)
        Positions of the table points (m).
    heading : array_like, shape (n,)
        Path heading at the table points (rad).
    curvature : array_like, shape (n,)
        Signed path curvature at the table points (1/m), positive for left turns.
    ds : float
        Arc-length spacing of the table (m).
    length : float
        Length of one lap (m).
    default_window : float
        Half-width (m of arc length) of the window searched by a hinted
        projection when no window is given.

    Attributes
    ----------
    x, y, heading, curvature : ndarray, shape (n,)
        The table (m, m, rad, 1/m); read-only by convention.
    n : int
        Number of table points.
    ds, length, default_window : float
        As the parameters (m).

    Notes
    -----
    Instances may be shared between threads: the scratch buffers of the
    window search are kept per thread, and they are not pickled.
    """

    def __init__(
        self,
        x: ArrayLike,
        y: ArrayLike,
        heading: ArrayLike,
        curvature: ArrayLike,
        *,
        ds: float,
        length: float,
        default_window: float,
    ) -> None:
        self.x = np.array(x, dtype=np.float64)
        self.y = np.array(y, dtype=np.float64)
        self.heading = np.array(heading, dtype=np.float64)
        self.curvature = np.array(curvature, dtype=np.float64)
        n = self.x.size
        shapes = {a.shape for a in (self.x, self.y, self.heading, self.curvature)}
        if shapes != {(n,)} or n < 4:
            raise ParameterError(f"PathProjector: need four 1-d tables of equal length >= 4, got {shapes}")
        if not (ds > 0.0 and length > 0.0 and default_window > 0.0):
            raise ParameterError(
                f"PathProjector: ds, length and default_window must be > 0, got {ds!r}, {length!r}, "
                f"{default_window!r}"
            )
        self.n = n
        self.ds = float(ds)
        self.length = float(length)
        self.default_window = float(default_window)
        self._xy = np.column_stack([self.x, self.y])  # KD-tree points, shape (n, 2)
        self._tree: cKDTree | None = None
        # Padded table: `pad` points of the end before the start and of the start after the
        # end, as one (2, n + 2 pad) array (rows x, y), so that a window of half-width up to
        # pad - 1 around any table point is one contiguous slice.
        self._pad = math.ceil(self.default_window / self.ds) + 2
        pad = self._pad
        pad_x = np.concatenate([self.x[-pad:], self.x, self.x[:pad]])
        pad_y = np.concatenate([self.y[-pad:], self.y, self.y[:pad]])
        self._pad_xy = np.ascontiguousarray(np.vstack([pad_x, pad_y]))
        # Search half-width (table steps) of the default window.
        self._default_half = max(math.ceil(self.default_window / self.ds), 2)
        # Per table point (x, y, heading, curvature, cos(heading), sin(heading)), as Python
        # floats for the scalar refinement (cheaper element access than numpy).
        self._lrow = [
            (xi, yi, th, k, math.cos(th), math.sin(th))
            for xi, yi, th, k in zip(
                self.x.tolist(), self.y.tolist(), self.heading.tolist(), self.curvature.tolist(), strict=True
            )
        ]
        # Scratch buffers of the hinted search, per (thread, half-width); see _search_buffers.
        self._buffers: dict[tuple[int, int], tuple[Any, ...]] = {}

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_buffers"] = {}  # scratch space: neither pickled nor shared between copies
        return state

    # ------------------------------------------------------------------ refinement
    def _refine(self, i: int, x: float, y: float) -> Projection:
        """Refine a projection starting from dense-table point ``i`` (scalar hot path)."""
        xi, yi, th, k, c, sn = self._lrow[i]
        ds = self.ds
        d = _newton_offset(x - xi, y - yi, c, sn, k)
        # Second step on the local second-order (clothoid-free) expansion.
        d, th_d, px, py, cd, sd = _local_point(d, ds, xi, yi, th, k, c, sn)
        d += _newton_offset(x - px, y - py, cd, sd, k)
        d, th_d, px, py, cd, sd = _local_point(d, ds, xi, yi, th, k, c, sn)
        lat = (y - py) * cd - (x - px) * sd
        length = self.length
        s = i * ds + d
        if s < 0.0:
            s += length
        elif s >= length:
            s -= length
        if s >= length:  # guards the rounding case s == length
            s = 0.0
        w = wrap_scalar(th_d)
        # Projection(s, lat, w) without the frozen dataclass's per-field __setattr__.
        proj = _new_object(Projection)
        attrs = proj.__dict__
        attrs["s"] = s
        attrs["lateral"] = lat
        attrs["heading"] = w
        return proj

    # ------------------------------------------------------------------ nearest table point
    def _nearest_global(self, xy: FloatArray) -> NDArray[np.intp]:
        """Index of the nearest table point to each point of ``xy`` (m), over the whole lap."""
        if self._tree is None:
            self._tree = cKDTree(self._xy)
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
        """Nearest table point within ``+-window`` (m) of ``s_hint`` (m), following the path."""
        n = self.n
        ds = self.ds
        half = math.ceil(window / ds)
        half = max(half, 2)
        centre = round((s_hint % self.length) / ds) % n
        if half + 1 <= self._pad:
            return self._search_padded(x, y, centre, half)
        best = centre
        for _ in range(MAX_RECENTRE):
            lo = centre - half
            hi = centre + half + 1
            idx = np.arange(lo, hi) % n
            ddx = self.x[idx] - x
            ddy = self.y[idx] - y
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
        n = self.n
        m = 2 * half + 1
        last = m - 1
        first = self._pad - half
        pad_xy = self._pad_xy
        best = centre
        for _ in range(MAX_RECENTRE):
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

    # ------------------------------------------------------------------ public interface
    def project_hinted(self, x: float, y: float, s_hint: float) -> Projection:
        """Hinted projection with the default window, without argument checks (hot path).

        The same result as ``project(x, y, s_hint)``, for floats ``x``, ``y`` (m)
        and ``s_hint`` (m); see :meth:`project`.
        """
        ds = self.ds
        n = self.n
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
        continuously.  The window wraps across ``s = 0``.  Where the path crosses itself (a
        bridge, :mod:`rkmpc.track.crossings`) the hinted search therefore stays on the pass of
        the hint (a bridge's passes are more than twice the default window apart); an unhinted
        projection of a point within a track width of the crossing may land on either pass.

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

        Raises
        ------
        ParameterError
            If ``window`` is given and not > 0.
        """
        x = float(x)
        y = float(y)
        if s_hint is None:
            i = int(self._nearest_global(np.array([x, y]))[()])
        elif window is None:
            return self.project_hinted(x, y, float(s_hint))
        else:
            w = float(window)
            if not (w > 0.0):
                raise ParameterError(f"path projection: window must be > 0 (m), got {window!r}")
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
        return f"PathProjector(n={self.n}, ds={self.ds:.6g}, length={self.length:.3f})"
