"""Condensed predictions of a time-invariant lifted linear model (computed once)."""

from __future__ import annotations

import numpy as np


def lifted_prediction(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray | None, horizon: int, *, first: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Stacked outputs of ``z+ = A z + B u``, ``y = C z + D u`` over a horizon.

    Returns ``(Mz, Mu)`` with ``[y_first; ...; y_{first+N-1}] = Mz z_0 + Mu [u_0; ...; u_{N-1}]``,
    where ``y_k`` uses ``u_k`` through ``D`` only when ``k < N``.

    Parameters
    ----------
    A : numpy.ndarray
        Lifted state matrix, shape (nz, nz).
    B : numpy.ndarray
        Input matrix, shape (nz, nu).
    C : numpy.ndarray
        Output matrix, shape (ny, nz).
    D : numpy.ndarray or None
        Feed-through matrix, shape (ny, nu), or None for none.
    horizon : int
        N, the number of inputs.
    first : int
        Index of the first output: 0 for ``y_0..y_{N-1}`` (outputs that depend on
        the input applied at the same step), 1 for ``y_1..y_N`` (predicted states).

    Returns
    -------
    Mz : numpy.ndarray
        Shape (N*ny, nz).
    Mu : numpy.ndarray
        Shape (N*ny, N*nu).
    """
    nz, nu = B.shape
    ny = C.shape[0]
    n = horizon
    # Powers A^k, k = 0..N.
    powers = [np.eye(nz)]
    for _ in range(n):
        powers.append(A @ powers[-1])
    Mz = np.empty((n, ny, nz))
    Mu = np.zeros((n, ny, n, nu))
    CAB = [C @ powers[k] @ B for k in range(n + 1)]
    for row in range(n):
        k = row + first
        Mz[row] = C @ powers[k]
        for j in range(min(k, n)):
            Mu[row, :, j, :] = CAB[k - 1 - j]
        if D is not None and k < n:
            Mu[row, :, k, :] += D
    return Mz.reshape(n * ny, nz), Mu.reshape(n * ny, n * nu)
