"""The Kalman update in square-root form, on small arrays with few numpy calls (the filter's hot path).

With the innovation covariance ``S = H P H^T + R = C C^T`` (Cholesky, computed on floats for the
1-, 2- and 3-row measurements the filter makes) and ``D = C^-1``, the update is
``u = D nu``, ``G = P H^T D^T``, ``x += G u``, ``P -= G G^T``. The normalised innovation
``|u|^2 = nu^T S^-1 nu`` is what the chi-square gate tests, and ``G G^T`` is exactly symmetric.
Every function returns new arrays (the prior a smoother keeps stays untouched).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["apply", "apply_one", "cholesky2", "cholesky3"]


def cholesky2(s00: float, s01: float, s11: float) -> tuple[float, float, float] | None:
    """Lower Cholesky factor ``(c00, c10, c11)`` of ``[[s00, s01], [s01, s11]]``; None if not positive."""
    if not s00 > 0.0:
        return None
    c00 = math.sqrt(s00)
    c10 = s01 / c00
    rest = s11 - c10 * c10
    if not rest > 0.0:
        return None
    return c00, c10, math.sqrt(rest)


def cholesky3(
    a: float, b: float, c: float, d: float, e: float, f: float
) -> tuple[float, float, float, float, float, float] | None:
    """Lower Cholesky factor ``(c00, c10, c20, c11, c21, c22)`` of ``[[a, b, c], [b, d, e], [c, e, f]]``.

    None when the matrix is not positive definite.
    """
    if not a > 0.0:
        return None
    c00 = math.sqrt(a)
    c10, c20 = b / c00, c / c00
    rest = d - c10 * c10
    if not rest > 0.0:
        return None
    c11 = math.sqrt(rest)
    c21 = (e - c10 * c20) / c11
    rest = f - c20 * c20 - c21 * c21
    if not rest > 0.0:
        return None
    return c00, c10, c20, c11, c21, math.sqrt(rest)


def apply(
    x: np.ndarray, P: np.ndarray, pht: np.ndarray, inverse_t: np.ndarray, u: tuple[float, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """``x + G u`` and ``P - G G^T`` with ``G = pht inverse_t`` (``pht = P H^T``, ``inverse_t = D^T``)."""
    G = pht.dot(inverse_t)
    return x + G.dot(np.array(u)), P - G.dot(G.T)


def apply_one(
    x: np.ndarray, P: np.ndarray, pht: np.ndarray, s: float, nu: float
) -> tuple[np.ndarray, np.ndarray]:
    """The scalar case: ``pht = P h`` (n,), ``s = h^T P h + r`` > 0, innovation ``nu``."""
    g = pht * (1.0 / math.sqrt(s))
    n = len(g)
    return x + pht * (nu / s), P - g.reshape(n, 1).dot(g.reshape(1, n))
