"""Online adaptation of a residual model's output map by recursive least squares.

The residual model of ``rkmpc`` predicts the nominal input ``U_p = C z + D u``
the kinematic model needs, from the lifted state ``z = psi(x)`` and the applied
command ``u``. On the car, every step reveals the ``U_p`` of the step just
driven (:func:`rkmpc.learning.data.residuals.kinematic_inverse` of two poses), so
the linear output map ``Theta = [C D]`` can keep learning while the lifting
``psi`` stays fixed. :class:`OutputRLS` does that, one output row at a time
with a shared covariance:

* ``phi = [z; u]``, ``e = y - Theta phi``;
* ``k = P phi / (lambda + phi' P phi)``, ``Theta <- Theta + e k'``,
  ``P <- (P - k phi' P) / lambda`` (forgetting factor ``lambda``);
* bounds: every entry stays within ``max_change`` times the row's largest
  trained magnitude of its trained value (projection), the trace of ``P`` is
  capped (no wind-up when the car drives straight), and a step whose error
  is larger than ``outlier`` times the running error scale is not learned from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_positive

__all__ = ["AdaptationConfig", "OutputRLS"]


@dataclass(frozen=True)
class AdaptationConfig:
    """Settings of :class:`OutputRLS`.

    Parameters
    ----------
    enabled : bool
        Off by default: the trained model is used as it is.
    forgetting : float
        ``lambda`` in (0, 1]: older steps weigh ``lambda^k``.
    initial_covariance : float
        ``P`` at the start, times the identity (trust in the trained map: small is strong).
    max_trace : float
        Cap of ``trace(P)``.
    max_change : float
        Largest change of an entry, as a fraction of the largest trained magnitude of its row.
    outlier : float
        Steps whose error exceeds this many running error scales are skipped.
    """

    enabled: bool = False
    forgetting: float = 0.995
    initial_covariance: float = 0.01
    max_trace: float = 10.0
    max_change: float = 0.5
    outlier: float = 5.0

    def __post_init__(self) -> None:
        require_positive(self, "forgetting", "initial_covariance", "max_trace", "max_change", "outlier")
        if self.forgetting > 1.0:
            raise ParameterError("AdaptationConfig.forgetting must be in (0, 1]")


class OutputRLS:
    """Recursive least squares on ``y = [C D] [z; u]`` with forgetting and bounds.

    Parameters
    ----------
    C, D : numpy.ndarray
        Trained output map, shapes (ny, nz) and (ny, nu).
    config : AdaptationConfig
        Settings.

    Attributes
    ----------
    C, D : numpy.ndarray
        The current map.
    updates, skipped : int
        Steps learned from, and steps skipped as outliers, since :meth:`reset`.
    """

    def __init__(self, C: np.ndarray, D: np.ndarray, config: AdaptationConfig) -> None:
        self._theta0 = np.hstack([np.asarray(C, dtype=float), np.asarray(D, dtype=float)])
        self._nz = C.shape[1]
        scale = np.max(np.abs(self._theta0), axis=1, keepdims=True)
        self._bound = config.max_change * np.where(scale > 0.0, scale, 1.0)
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Back to the trained map."""
        n = self._theta0.shape[1]
        self._theta = self._theta0.copy()
        self._P = self.config.initial_covariance * np.eye(n)
        self._scale: np.ndarray | None = None
        self.updates = 0
        self.skipped = 0

    @property
    def C(self) -> np.ndarray:
        return self._theta[:, : self._nz]

    @property
    def D(self) -> np.ndarray:
        return self._theta[:, self._nz :]

    def update(self, z: np.ndarray, u: np.ndarray, y: np.ndarray) -> bool:
        """Learn from one step: lifted state ``z``, input ``u``, observed output ``y``; True if learned."""
        phi = np.concatenate([np.asarray(z, dtype=float), np.asarray(u, dtype=float)])
        error = np.asarray(y, dtype=float) - self._theta @ phi
        if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(error))):
            self.skipped += 1
            return False
        cfg = self.config
        magnitude = np.abs(error)
        if self._scale is None:
            self._scale = np.maximum(magnitude, 1e-6)
        elif np.any(magnitude > cfg.outlier * self._scale):
            self.skipped += 1
            self._scale = 0.99 * self._scale + 0.01 * np.minimum(magnitude, cfg.outlier * self._scale)
            return False
        else:
            self._scale = 0.99 * self._scale + 0.01 * np.maximum(magnitude, 1e-6)
        P_phi = self._P @ phi
        gain = P_phi / (cfg.forgetting + float(phi @ P_phi))
        self._theta += np.outer(error, gain)
        np.clip(self._theta, self._theta0 - self._bound, self._theta0 + self._bound, out=self._theta)
        self._P = (self._P - np.outer(gain, P_phi)) / cfg.forgetting
        trace = float(np.trace(self._P))
        if trace > cfg.max_trace:
            self._P *= cfg.max_trace / trace
        self.updates += 1
        return True
