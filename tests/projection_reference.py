"""Plain reference implementation of the projection of a point onto a path.

:func:`project_plain` computes the same projection as
:meth:`rkmpc.track.projection.PathProjector.project` (and so as
:meth:`rkmpc.track.path.Path.project`) in the most direct way: a search for the
nearest point of the dense table (exhaustive over the lap without a hint,
within a window around the hint otherwise), followed by the same two-step
local Newton refinement.  It is written to be read and to check the fast
implementation against, not to be fast: no padded tables, no scratch
buffers, no KD-tree.

The arithmetic is the same as that of the fast code, operation for operation,
so both give the same floats (the tests compare them).  The only possible
difference is in the global search, where the KD-tree and the exhaustive
search may pick different table points when two are equally near to within
rounding.
"""

from __future__ import annotations

import math

import numpy as np

from rkmpc.core.angles import wrap_scalar
from rkmpc.core.errors import ParameterError
from rkmpc.track.path import Path
from rkmpc.track.projection import MAX_RECENTRE, PathProjector, Projection

__all__ = ["nearest_table_point", "project_plain", "refine_from_table_point"]


def nearest_table_point(
    table: PathProjector, x: float, y: float, s_hint: float | None = None, window: float | None = None
) -> int:
    """Index of the table point nearest to ``(x, y)``, over the lap or in a window around a hint.

    Without a hint every table point is compared.  With a hint the window of
    table points ``centre - half ... centre + half`` (indices modulo the table
    size) is searched, where ``centre`` is the table point nearest to the hint
    in arc length and ``half = max(ceil(window / ds), 2)``; if the nearest
    point is on the edge of the window, the window is centred on it and the
    search repeated (at most ``MAX_RECENTRE`` searches in all).  Ties go to the
    first point of the window.

    Parameters
    ----------
    table : PathProjector
        The dense table of the path.
    x, y : float
        Point (m).
    s_hint : float, optional
        Arc length (m) near which the nearest point is expected; any real value.
    window : float, optional
        Half-width (m of arc length) of the searched window; defaults to
        ``table.default_window``.  Ignored without a hint.

    Returns
    -------
    int
        Table index in ``[0, table.n)``.
    """
    if s_hint is None:
        dx = table.x - x
        dy = table.y - y
        return int(np.argmin(dx * dx + dy * dy))
    n = table.n
    w = table.default_window if window is None else window
    half = max(math.ceil(w / table.ds), 2)
    centre = round((s_hint % table.length) / table.ds) % n
    best = centre
    for _ in range(MAX_RECENTRE):
        lo = centre - half
        hi = centre + half + 1
        idx = np.arange(lo, hi) % n
        dx = table.x[idx] - x
        dy = table.y[idx] - y
        j = int(np.argmin(dx * dx + dy * dy))
        best = (lo + j) % n
        on_edge = j == 0 or j == hi - lo - 1
        if not on_edge or 2 * half + 1 >= n:  # inside the window, or the window is the whole lap
            break
        centre = best
    return best


def refine_from_table_point(table: PathProjector, i: int, x: float, y: float) -> Projection:
    """Refine the projection of ``(x, y)`` from table point ``i`` by two Newton steps.

    Near table point ``i`` (arc length ``s_i = i * ds``, position ``p_i``,
    heading ``th``, curvature ``k``) the path is approximated to second order
    in the offset ``d`` along it::

        p(d) = p_i + d * t - (k d**2 / 2) * n,    heading(d) = th + k * d,

    with ``t = (cos th, sin th)``, ``n = (-sin th, cos th)``.  From ``d = 0``, each
    step writes the point in the frame at ``p(d)`` (``along`` the heading, ``lat``
    to its left) and moves ``d`` by ``along / max(1 - k * lat, 0.1)`` (Newton on a
    circle of curvature ``k``), keeping ``|d| <= ds``.  After two steps the
    lateral offset and heading are taken at the final ``p(d)``.

    Parameters
    ----------
    table : PathProjector
        The dense table of the path.
    i : int
        Table index to start from, in ``[0, table.n)``.
    x, y : float
        Point (m).

    Returns
    -------
    Projection
        ``s = s_i + d`` in ``[0, length)`` (m), lateral offset (m, left positive), heading (rad).
    """
    xi, yi = float(table.x[i]), float(table.y[i])
    th, k = float(table.heading[i]), float(table.curvature[i])
    c, sn = math.cos(th), math.sin(th)
    ds = table.ds

    def local_frame(d: float) -> tuple[float, float, float]:
        """Coordinates (along, lat) (m) of the point in the frame at ``p(d)``, and its heading (rad)."""
        th_d = th + k * d
        half_kdd = 0.5 * k * d * d
        px = xi + c * d - half_kdd * sn
        py = yi + sn * d + half_kdd * c
        cd, sd = math.cos(th_d), math.sin(th_d)
        along = (x - px) * cd + (y - py) * sd
        lat = (y - py) * cd - (x - px) * sd
        return along, lat, th_d

    d = 0.0
    for _ in range(2):
        along, lat, _ = local_frame(d)
        d = min(max(d + along / max(1.0 - k * lat, 0.1), -ds), ds)
    _, lat, th_d = local_frame(d)

    length = table.length
    s = i * ds + d
    if s < 0.0:
        s += length
    elif s >= length:
        s -= length
    if s >= length:  # rounding: s == length after subtracting
        s = 0.0
    return Projection(s=s, lateral=lat, heading=wrap_scalar(th_d))


def project_plain(
    target: PathProjector | Path,
    x: float,
    y: float,
    s_hint: float | None = None,
    window: float | None = None,
) -> Projection:
    """Project a point onto a path, plainly: nearest table point, then two Newton steps.

    The reference for :meth:`rkmpc.track.path.Path.project`: same arguments,
    same result (see the module docstring), computed by
    :func:`nearest_table_point` and :func:`refine_from_table_point`.

    Parameters
    ----------
    target : PathProjector or Path
        The path, or its projector.
    x, y : float
        Point (m).
    s_hint : float, optional
        Arc length (m) near which the projection is expected; any real value.
        Without it the nearest point over the whole lap is found.
    window : float, optional
        Half-width (m of arc length) of the window searched around ``s_hint``;
        defaults to the path's default window.

    Returns
    -------
    Projection
        ``s`` in ``[0, length)`` (m), signed lateral offset (m, left positive)
        and heading (rad).

    Raises
    ------
    ParameterError
        If ``window`` is given and not > 0.
    """
    table = target.projector if isinstance(target, Path) else target
    x = float(x)
    y = float(y)
    if window is not None and not float(window) > 0.0:
        raise ParameterError(f"project_plain: window must be > 0 (m), got {window!r}")
    hint = None if s_hint is None else float(s_hint)
    win = None if window is None else float(window)
    i = nearest_table_point(table, x, y, hint, win)
    return refine_from_table_point(table, i, x, y)
