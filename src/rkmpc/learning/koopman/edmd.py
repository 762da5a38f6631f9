"""Closed-form least-squares fits of the lifted linear model (extended DMD).

With lifted states ``Z`` (n_samples, nz), inputs ``U`` (n_samples, nu) and successors ``Z_next``,
:func:`fit_dynamics` solves

    min_{A, B}  sum_k || z_{k+1} - (A z_k + B u_k) ||^2  (+ ridge penalty),

i.e. ``[A, B] = Z_next^T [Z, U]^{T+}`` in the row-sample layout used here, the pseudo-inverse formula
of Korda & Mezic (2018) quoted in the paper (Sec. III-B). :func:`fit_output` fits the output map
``y_k = C z_k + D u_k`` the same way.
"""

from __future__ import annotations

import numpy as np

from rkmpc.core.errors import ParameterError

__all__ = ["fit_dynamics", "fit_output", "ridge_lstsq"]


def _matrix(value: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim != 2:
        raise ParameterError(f"{name} must be a 2-D array (n_samples, n_features), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} contains NaN or infinite values")
    return array


def ridge_lstsq(Phi: np.ndarray, T: np.ndarray, ridge: float = 0.0) -> np.ndarray:
    """Solve ``min_W ||Phi W - T||^2 / n + ridge ||W||^2`` for ``W``.

    Parameters
    ----------
    Phi : ndarray, shape (n_samples, p)
        Regressors.
    T : ndarray, shape (n_samples, q)
        Targets.
    ridge : float
        Non-negative Tikhonov weight, dimensionless: the penalty applies to the coefficients of the
        regressors scaled to unit root-mean-square, relative to their sample-averaged Gram matrix, so it
        does not depend on the units of the columns of ``Phi``. ``0`` gives the least-squares solution
        (minimum-norm in the scaled regressors).

    Returns
    -------
    ndarray, shape (p, q)

    Notes
    -----
    With ``S = diag(rms of the columns of Phi)`` and ``Phi_s = Phi S^-1``, the ridge problem is solved as
    the ordinary least-squares problem ``[Phi_s; sqrt(n ridge) I] V = [T; 0]`` (which keeps the
    conditioning of ``Phi_s`` rather than squaring it as the normal equations would), and ``W = S^-1 V``.
    """
    ridge = float(ridge)
    if not (np.isfinite(ridge) and ridge >= 0):
        raise ParameterError(f"ridge must be a non-negative number, got {ridge}")
    n, p = Phi.shape
    scale = np.sqrt(np.mean(Phi**2, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    Phi = Phi / scale
    if ridge > 0:
        Phi = np.vstack([Phi, np.sqrt(n * ridge) * np.eye(p)])
        T = np.vstack([T, np.zeros((p, T.shape[1]))])
    V, *_ = np.linalg.lstsq(Phi, T, rcond=None)
    return V / scale[:, None]


def _fit_linear(Z: np.ndarray, U: np.ndarray, T: np.ndarray, ridge: float) -> tuple[np.ndarray, np.ndarray]:
    """The matrices ``M`` (q, nz) and ``N`` (q, nu) of ``t_k = M z_k + N u_k``, by :func:`ridge_lstsq`."""
    nz = Z.shape[1]
    W = ridge_lstsq(np.hstack([Z, U]), T, ridge)
    return W[:nz].T.copy(), W[nz:].T.copy()


def fit_dynamics(
    Z: np.ndarray, U: np.ndarray, Z_next: np.ndarray, ridge: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``A``, ``B`` of ``z_{k+1} = A z_k + B u_k``.

    Parameters
    ----------
    Z : ndarray, shape (n_samples, nz)
        Lifted states.
    U : ndarray, shape (n_samples, nu)
        Inputs (``nu`` may be 0).
    Z_next : ndarray, shape (n_samples, nz)
        Lifted successor states.
    ridge : float
        Tikhonov weight (see :func:`ridge_lstsq`); 0 for the plain pseudo-inverse solution.

    Returns
    -------
    A : ndarray, shape (nz, nz)
    B : ndarray, shape (nz, nu)
    """
    Z = _matrix(Z, "Z")
    U = _matrix(U, "U")
    Z_next = _matrix(Z_next, "Z_next")
    if Z_next.shape != Z.shape:
        raise ParameterError(f"Z_next has shape {Z_next.shape}, Z has {Z.shape}")
    if U.shape[0] != Z.shape[0]:
        raise ParameterError(f"U has {U.shape[0]} samples, Z has {Z.shape[0]}")
    return _fit_linear(Z, U, Z_next, ridge)


def fit_output(
    Z: np.ndarray, U: np.ndarray | None, Y: np.ndarray, ridge: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``C``, ``D`` of ``y_k = C z_k + D u_k``.

    Parameters
    ----------
    Z : ndarray, shape (n_samples, nz)
        Lifted states.
    U : ndarray, shape (n_samples, nu), or None
        Inputs; ``None`` fits ``y = C z`` alone and returns ``D`` of shape (ny, 0).
    Y : ndarray, shape (n_samples, ny)
        Output targets.
    ridge : float
        Tikhonov weight (see :func:`ridge_lstsq`).

    Returns
    -------
    C : ndarray, shape (ny, nz)
    D : ndarray, shape (ny, nu)
    """
    Z = _matrix(Z, "Z")
    Y = _matrix(Y, "Y")
    U = np.zeros((Z.shape[0], 0)) if U is None else _matrix(U, "U")
    if Y.shape[0] != Z.shape[0] or U.shape[0] != Z.shape[0]:
        raise ParameterError(f"sample counts differ: Z {Z.shape[0]}, U {U.shape[0]}, Y {Y.shape[0]}")
    return _fit_linear(Z, U, Y, ridge)
