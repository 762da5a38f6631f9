"""Where a closed line crosses itself, and whether the crossing is a bridge or a fold.

Real tracks may pass over themselves (Suzuka's figure-8: one part of the lap runs on a bridge
over another).  Their centre line then crosses itself in the plane, and that is fine as long as
the two parts are *different parts of the lap*: a car on one never confuses it with the other
because every projection after the first is hinted (:meth:`rkmpc.track.path.Path.project`)
and searches only a window of arc length around the car's previous position.

**The rule.**  A crossing of the line is a *bridge* when

* the two passes are far apart along the lap: their arc-length separation, measured the
  shorter way round the closed lap, is at least :func:`min_bridge_separation`, i.e. the
  largest of :data:`BRIDGE_MIN_WIDTHS` (10) full track widths at the crossing,
  :data:`BRIDGE_MIN_LAP_FRACTION` (a tenth) of the lap, and twice the projection's search
  window (so the hinted window around one pass never reaches the other);
* and they cross at :data:`BRIDGE_MIN_ANGLE` (20 degrees) or more (a shallow crossing is two
  parts of the track merging, not a bridge).

Any other crossing is a *fold*: the line folds back on itself locally (a small loop, a
zig-zag, a spike) and the track is refused.  A line that folds back onto its previous
segment is a fold with separation 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from rkmpc.track.path import Path

__all__ = [
    "BRIDGE_MIN_ANGLE",
    "BRIDGE_MIN_LAP_FRACTION",
    "BRIDGE_MIN_WIDTHS",
    "Crossing",
    "SegmentCrossing",
    "bridge_problem",
    "crossings_of_table",
    "find_self_intersection",
    "min_bridge_separation",
    "path_crossings",
    "segment_crossings",
]

FloatArray = NDArray[np.float64]

#: A bridge's two passes are at least this many full track widths apart along the lap.
BRIDGE_MIN_WIDTHS = 10.0
#: ... and at least this share of the lap apart.
BRIDGE_MIN_LAP_FRACTION = 0.1
#: A bridge's two passes cross at this angle (rad) or more.
BRIDGE_MIN_ANGLE = math.radians(20.0)


@dataclass(frozen=True)
class SegmentCrossing:
    """Two crossing segments of a closed polyline.

    Parameters
    ----------
    i, j : int
        Indices of the segments, ``i < j``; segment ``k`` joins point ``k`` to point ``k + 1``
        (the last one back to the first).
    t_i, t_j : float
        Where they meet, as a fraction of each segment (0 at its start, 1 at its end).
    x, y : float
        Meeting point (m).
    sin_angle : float
        Sine of the (acute) crossing angle; 0 for segments that overlap or fold back.
    """

    i: int
    j: int
    t_i: float
    t_j: float
    x: float
    y: float
    sin_angle: float


@dataclass(frozen=True)
class Crossing:
    """A place where a track's line crosses itself (a bridge).

    Parameters
    ----------
    s_first, s_second : float
        Arc length (m) of the line's two passes through the crossing, ``s_first < s_second``.
    x, y : float
        The crossing point (m).
    angle : float
        Crossing angle (rad), in ``[0, pi / 2]``.
    separation : float
        Arc length (m) between the two passes, the shorter way round the lap.
    """

    s_first: float
    s_second: float
    x: float
    y: float
    angle: float
    separation: float


def _orient(o: FloatArray, d: FloatArray, q: FloatArray) -> FloatArray:
    return (d[:, 0] - o[:, 0]) * (q[:, 1] - o[:, 1]) - (d[:, 1] - o[:, 1]) * (q[:, 0] - o[:, 0])


def segment_crossings(xy: ArrayLike) -> list[SegmentCrossing]:
    """Every pair of crossing segments of a closed polyline, in order of ``(i, j)``.

    Candidate pairs come from a KD-tree on segment midpoints (two segments can only meet if
    their midpoints are closer than the longest segment) and are tested with vectorised
    orientation tests.  Adjacent segments count only when they fold back onto each other (a
    180-degree reversal; reported with ``t_i = 1, t_j = 0``).

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Points of the closed polyline (m), first point not repeated.
    """
    p = np.asarray(xy, dtype=float)
    n = p.shape[0]
    if n < 3:
        return []
    a = p
    b = np.roll(p, -1, axis=0)
    seg = b - a
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    out: list[SegmentCrossing] = []

    nxt = np.roll(seg, -1, axis=0)
    cross_adj = seg[:, 0] * nxt[:, 1] - seg[:, 1] * nxt[:, 0]
    dot_adj = np.einsum("ij,ij->i", seg, nxt)
    norm = seg_len * np.roll(seg_len, -1)
    for k in np.flatnonzero((dot_adj < 0.0) & (np.abs(cross_adj) <= 1e-12 * np.maximum(norm, 1e-300))):
        i, j = int(k), (int(k) + 1) % n
        t_i, t_j = (1.0, 0.0) if i < j else (0.0, 1.0)
        out.append(SegmentCrossing(min(i, j), max(i, j), t_i, t_j, float(b[k, 0]), float(b[k, 1]), 0.0))

    mid = 0.5 * (a + b)
    radius = float(seg_len.max()) * (1.0 + 1e-9)
    pairs = cKDTree(mid).query_pairs(radius, output_type="ndarray")
    if pairs.size:
        i, j = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
        gap = j - i
        keep = (gap != 1) & (gap != n - 1)
        i, j = i[keep], j[keep]
        a1, b1, a2, b2 = a[i], b[i], a[j], b[j]
        o1 = _orient(a1, b1, a2)
        o2 = _orient(a1, b1, b2)
        o3 = _orient(a2, b2, a1)
        o4 = _orient(a2, b2, b1)
        hit = (o1 * o2 <= 0.0) & (o3 * o4 <= 0.0)
        collinear = (o1 == 0.0) & (o2 == 0.0)
        if np.any(collinear):
            # Collinear pairs meet only if their bounding boxes overlap.
            lo1, hi1 = np.minimum(a1, b1), np.maximum(a1, b1)
            lo2, hi2 = np.minimum(a2, b2), np.maximum(a2, b2)
            overlap = np.all((lo1 <= hi2) & (lo2 <= hi1), axis=1)
            hit = np.where(collinear, overlap, hit)
        for k in np.flatnonzero(hit):
            den_i = o3[k] - o4[k]
            den_j = o1[k] - o2[k]
            t_i = float(o3[k] / den_i) if den_i != 0.0 else 0.0
            t_j = float(o1[k] / den_j) if den_j != 0.0 else 0.0
            point = a1[k] + t_i * (b1[k] - a1[k])
            sin_angle = abs(float(seg[i[k], 0] * seg[j[k], 1] - seg[i[k], 1] * seg[j[k], 0])) / max(
                float(seg_len[i[k]] * seg_len[j[k]]), 1e-300
            )
            out.append(
                SegmentCrossing(
                    int(i[k]), int(j[k]), t_i, t_j, float(point[0]), float(point[1]), min(sin_angle, 1.0)
                )
            )
    out.sort(key=lambda c: (c.i, c.j))
    return out


def min_bridge_separation(length: float, width: float, window: float = 0.0) -> float:
    """Least arc-length separation (m) of a bridge's two passes (see the module's rule).

    Parameters
    ----------
    length : float
        Length of the lap (m).
    width : float
        Full track width at the crossing (m); 0 for a line without widths (a race line).
    window : float, default 0
        Half-width (m) of the hinted projection's search window on the line.
    """
    return max(BRIDGE_MIN_WIDTHS * width, BRIDGE_MIN_LAP_FRACTION * length, 2.0 * window)


def bridge_problem(
    separation: float, angle: float, length: float, width: float, window: float = 0.0
) -> str | None:
    """Why a crossing is no bridge but a fold (None when it is a bridge).

    Parameters
    ----------
    separation : float
        Arc length (m) between the two passes, the shorter way round.
    angle : float
        Crossing angle (rad), in ``[0, pi / 2]``.
    length, width, window : float
        As for :func:`min_bridge_separation`.
    """
    need = min_bridge_separation(length, width, window)
    if separation < need:
        return (
            f"the two passes are only {separation:.3g} m apart along the lap: the line folds back on "
            f"itself (a bridge's passes are at least {need:.3g} m apart: the largest of "
            f"{BRIDGE_MIN_WIDTHS:g} track widths, {BRIDGE_MIN_LAP_FRACTION:g} of the lap and twice the "
            "projection window)"
        )
    if angle < BRIDGE_MIN_ANGLE:
        return (
            f"the two passes cross at only {math.degrees(angle):.3g} degrees (a bridge crosses at "
            f"{math.degrees(BRIDGE_MIN_ANGLE):g} degrees or more): two parts of the track overlap"
        )
    return None


def crossings_of_table(xy: ArrayLike, s: ArrayLike, length: float) -> list[Crossing]:
    """The crossings of a closed line sampled densely at arc lengths ``s`` (m).

    Hits of neighbouring sample segments at the same place (a crossing exactly through a
    sample point) are merged into one.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Samples of the line (m), first not repeated.
    s : array_like, shape (n,)
        Their arc lengths (m), increasing, in ``[0, length)``.
    length : float
        Length of the lap (m).
    """
    pts = np.asarray(xy, dtype=float)
    s_arr = np.asarray(s, dtype=float)
    s_next = np.append(s_arr[1:], length)
    out: list[Crossing] = []
    step = float(np.max(np.diff(np.append(s_arr, length))))
    for hit in segment_crossings(pts):
        s1 = float(s_arr[hit.i] + hit.t_i * (s_next[hit.i] - s_arr[hit.i]))
        s2 = float(s_arr[hit.j] + hit.t_j * (s_next[hit.j] - s_arr[hit.j]))
        s1, s2 = sorted((s1 % length, s2 % length))

        def near(a: float, b: float) -> bool:
            d = abs(a - b) % length
            return min(d, length - d) < 3 * step

        if any(near(c.s_first, s1) and near(c.s_second, s2) for c in out):
            continue
        if any(near(c.s_first, s2) and near(c.s_second, s1) for c in out):
            continue
        separation = min(s2 - s1, length - (s2 - s1))
        angle = math.asin(hit.sin_angle)
        out.append(Crossing(s1, s2, hit.x, hit.y, angle, separation))
    return out


def path_crossings(path: Path) -> list[Crossing]:
    """The crossings of a path's smoothed line, sampled on its projection table (about 2 cm)."""
    table = path.projector
    return crossings_of_table(np.column_stack([table.x, table.y]), np.arange(table.n) * table.ds, path.length)


def find_self_intersection(xy: ArrayLike) -> tuple[int, int] | None:
    """Find two crossing segments of a closed polyline (bridge or not).

    Segment ``i`` joins point ``i`` to point ``i + 1`` (the last one joins the last point to
    the first); see :func:`segment_crossings`.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Points of the closed polyline (m), first point not repeated.

    Returns
    -------
    tuple of int or None
        Indices ``(i, j)``, ``i < j``, of the first pair of intersecting segments, or None if the
        polyline is simple.
    """
    hits = segment_crossings(xy)
    return None if not hits else (hits[0].i, hits[0].j)
