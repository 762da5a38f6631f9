"""Point sequences of closed lines: dropping repeated points before a spline is fitted."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["dedupe_closed", "dedupe_mask"]

FloatArray = NDArray[np.float64]


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
