"""Validation of the training arrays of a :class:`~rkmpc.learning.koopman.model.KoopmanModel`.

Every check raises :class:`~rkmpc.core.errors.ParameterError` naming the array at fault.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError

__all__ = ["checked_data", "finite_array"]


def finite_array(value: Any, name: str, ndim: int) -> np.ndarray:
    """``value`` as a float array of ``ndim`` dimensions, all finite; ParameterError naming ``name``."""
    array = np.asarray(value, dtype=float)
    if array.ndim != ndim:
        raise ParameterError(f"{name} must be a {ndim}-D array, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} contains NaN or infinite values")
    return array


def checked_data(
    X: Any, U: Any, X_next: Any, Y: Any, windows: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, tuple[np.ndarray, np.ndarray] | None]:
    """Validated training arrays of :meth:`~rkmpc.learning.koopman.model.KoopmanModel.fit`.

    Parameters
    ----------
    X, X_next : array_like, shape (N, nx)
        States and successors, N >= 2, nx >= 1.
    U : array_like, shape (N, nu)
        Inputs.
    Y : array_like, shape (N, ny), optional
        Output targets.
    windows : pair (Xw (M, H+1, nx), Uw (M, H, nu)), optional
        Consecutive sequences, H >= 1, M >= 1.

    Returns
    -------
    X, U, X_next, Y, windows
        As float arrays (``Y`` and ``windows`` None when not given).

    Raises
    ------
    ParameterError
        Naming the array at fault: wrong dimensions or shapes, or a NaN or infinite value.
    """
    X = finite_array(X, "X", 2)
    U = finite_array(U, "U", 2)
    X_next = finite_array(X_next, "X_next", 2)
    n, nx = X.shape
    if X_next.shape != X.shape:
        raise ParameterError(f"X_next has shape {X_next.shape}, X has {X.shape}")
    if U.shape[0] != n:
        raise ParameterError(f"U has {U.shape[0]} samples, X has {n}")
    if n < 2 or nx < 1:
        raise ParameterError(f"need at least 2 samples of at least 1 feature, got X of shape {X.shape}")
    nu = U.shape[1]
    if Y is not None:
        Y = finite_array(Y, "Y", 2)
        if Y.shape[0] != n:
            raise ParameterError(f"Y has {Y.shape[0]} samples, X has {n}")
    if windows is not None:
        if len(windows) != 2:
            raise ParameterError("windows must be a pair (Xw, Uw)")
        Xw = finite_array(windows[0], "windows[0]", 3)
        Uw = finite_array(windows[1], "windows[1]", 3)
        if Xw.shape[0] != Uw.shape[0] or Xw.shape[1] != Uw.shape[1] + 1 or Xw.shape[2] != nx:
            raise ParameterError(
                f"windows must have shapes (M, H+1, {nx}) and (M, H, {nu}), got {Xw.shape} and {Uw.shape}"
            )
        if Uw.shape[2] != nu or Uw.shape[1] < 1 or Uw.shape[0] < 1:
            raise ParameterError(f"windows[1] must have shape (M, H>=1, {nu}), got {Uw.shape}")
        windows = (Xw, Uw)
    return X, U, X_next, Y, windows
