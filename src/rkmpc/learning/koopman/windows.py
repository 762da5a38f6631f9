"""Windows of consecutive transitions found in one-step data, for the multi-step term of a loss.

Plain numpy: :class:`~rkmpc.learning.koopman.mlp.MLPLifting` takes its rollout windows from here when
the caller gives none.
"""

from __future__ import annotations

import numpy as np

__all__ = ["consecutive_windows"]


def consecutive_windows(
    X: np.ndarray, U: np.ndarray, X_next: np.ndarray, steps: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """Windows of ``steps`` consecutive transitions found in one-step data.

    Transition ``k`` is followed by ``k + 1`` when ``X_next[k] == X[k + 1]`` exactly (as for samples
    taken in order from trajectories).

    Parameters
    ----------
    X, X_next : ndarray, shape (N, nx)
    U : ndarray, shape (N, nu)
    steps : int
        Window length in transitions (H).

    Returns
    -------
    (Xw, Uw) with shapes (M, H+1, nx) and (M, H, nu), or None when there is no such window.
    """
    n = X.shape[0]
    if steps < 1 or n < steps:
        return None
    linked = np.all(X_next[:-1] == X[1:], axis=1)  # (N-1,)
    # A window starting at i needs links i .. i+steps-2 (steps-1 of them).
    ok = np.ones(n - steps + 1, dtype=bool)
    if steps > 1:
        count = np.concatenate([[0], np.cumsum(linked)])
        starts = np.arange(n - steps + 1)
        ok = (count[starts + steps - 1] - count[starts]) == steps - 1
    starts = np.flatnonzero(ok)
    if starts.size == 0:
        return None
    offsets = np.arange(steps)
    Xw = np.concatenate([X[starts[:, None] + offsets], X_next[starts + steps - 1][:, None, :]], axis=1)
    Uw = U[starts[:, None] + offsets]
    return Xw, Uw
