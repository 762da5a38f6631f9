"""Small helpers shared by the liftings: input standardisation and checks of arrays and settings.

Used by :mod:`rkmpc.learning.koopman.mlp` and :mod:`rkmpc.learning.koopman.rbf`; plain numpy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rkmpc.core.errors import ParameterError

__all__ = ["as_vector", "check_input", "standardisation"]


def standardisation(X: np.ndarray, min_std: float = 1e-8) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and standard deviation of ``X``, shape (nx,) each.

    Features whose spread is below ``min_std`` (constant columns) get a standard deviation of 1 so that
    dividing by it is harmless.

    Parameters
    ----------
    X : ndarray, shape (n_samples, nx)
        Samples, in the units of the features.
    min_std : float
        Smallest spread taken as a real one (units of the features).

    Returns
    -------
    mean, std : ndarray, shape (nx,)
    """
    X = np.asarray(X, dtype=float)
    mean = X.mean(axis=0)
    std = X.std(axis=0)
    std = np.where(std < min_std, 1.0, std)
    return mean, std


def as_vector(values: np.ndarray | Sequence[float], name: str, size: int | None = None) -> np.ndarray:
    """``values`` as a finite float vector (a copy), of length ``size`` when given.

    Raises
    ------
    ParameterError
        Naming ``name``, for a wrong length or a non-finite entry.
    """
    array = np.array(values, dtype=float).reshape(-1)
    if size is not None and array.shape != (size,):
        raise ParameterError(f"{name} must have shape ({size},), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} must be finite")
    return array


def check_input(X: np.ndarray, nx: int, who: str) -> np.ndarray:
    """States to lift as a float array of shape (n_samples, nx) or (nx,); ParameterError naming ``who``."""
    X = np.asarray(X, dtype=float)
    if X.ndim not in (1, 2) or X.shape[-1] != nx:
        raise ParameterError(f"{who}: expected states of shape (n_samples, {nx}) or ({nx},), got {X.shape}")
    return X
