"""Angles: the one wrapping convention of rkmpc, ``(-pi, pi]``.

Every heading difference in the package (tracking errors, local frames, the
data augmentation, residual labels, the projection onto a path) is wrapped by
:func:`wrap_angle`. The same mapping is written out for one float in
:func:`wrap_scalar`, for the per-step hot paths; the two agree exactly (a
test checks it).
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["TWO_PI", "branch_shift", "wrap_angle", "wrap_scalar"]

TWO_PI = 2.0 * math.pi


@overload
def wrap_angle(angle: float) -> float: ...


@overload
def wrap_angle(angle: NDArray[Any]) -> NDArray[np.float64]: ...


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64] | float:
    """Wrap angles (rad) into ``(-pi, pi]``, elementwise.

    Parameters
    ----------
    angle : float or array_like
        Angle(s) in rad, any shape.

    Returns
    -------
    float or numpy.ndarray
        Wrapped angle(s) in rad, same shape (a float for a scalar input).
    """
    a = np.asarray(angle, dtype=float)
    # pi - fmod(pi - a, 2 pi) lies in (-pi, 3 pi); one fold of 2 pi brings it into (-pi, pi].
    w = np.pi - np.fmod(np.pi - a, TWO_PI)
    w = np.where(w <= -np.pi, w + TWO_PI, w)
    w = np.where(w > np.pi, w - TWO_PI, w)
    if w.ndim == 0:
        return float(w)
    return w


def wrap_scalar(angle: float) -> float:
    """:func:`wrap_angle` of one float (rad), without numpy: the same result, bit for bit (NaN for inf)."""
    if not math.isfinite(angle):
        return math.nan
    w = math.pi - math.fmod(math.pi - angle, TWO_PI)
    if w <= -math.pi:
        w += TWO_PI
    elif w > math.pi:
        w -= TWO_PI
    return w


def branch_shift(angle: float) -> float:
    """The multiple of ``2 pi`` nearest to ``angle`` (rad).

    Subtracting it from a continuous sequence of headings moves the sequence to
    the branch on which ``angle`` (one of its entries, or its offset from a
    reference heading) lies within ``pi`` of zero, without breaking its continuity.
    """
    return TWO_PI * round(angle / TWO_PI)
