"""How far to trust a learned correction: an out-of-distribution guard for the residual MPCs.

A residual model is learned from two laps. Where the car leaves the states it
was trained on (a slippery patch, a heavier car, a corner faster than any in
the data), or where the model's recent predictions stop matching the car, its
correction is a guess. :class:`CorrectionTrust` turns both signs into a trust
``w`` in [0, 1] and the controller applies ``w`` times the correction, fading
toward the LMPC's own command:

* **range**: the features ``x`` against the model's training range
  ``[x_min_, x_max_]``: ``out = max_i max(x_min_i - x_i, x_i - x_max_i, 0) / span_i``;
  ``w_range = clip(1 - (out - range_margin) / range_fade, 0, 1)``;
* **prediction error**: each step the model predicts the next features,
  ``x_hat = Cx (A z + B u)``; at the next step
  ``e = max_i |x_i - x_hat_i| / span_i``, smoothed as
  ``e_bar <- (1 - a) e_bar + a e``;
  ``w_error = clip((error_high - e_bar) / (error_high - error_low), 0, 1)``;
* ``w = min(w_range, w_error)``.

The thresholds are fractions of the training span of each feature, so they
carry over between cars and scales. A feature that hardly varied in training
(the speed on an oval, held at the profile's top speed) would make ordinary
noise look like a large error, so each span is at least ``min_span`` times
the feature's largest magnitude in training: ``span_i = max(x_max_i - x_min_i,
min_span * max(|x_min_i|, |x_max_i|))``. Features whose range holds zero (yaw
rate, wheel angle) are not changed by it. Every step with ``w < 1`` is counted,
by the sign that caused it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_nonnegative, require_positive

__all__ = ["CorrectionTrust", "TrustConfig"]


@dataclass(frozen=True)
class TrustConfig:
    """Settings of :class:`CorrectionTrust` (fractions of each feature's training span).

    Parameters
    ----------
    enabled : bool
        False trusts every correction fully (the guard only counts).
    range_margin : float
        How far outside the training range (-) a feature may go before trust falls.
    range_fade : float
        Further distance (-) over which trust falls from 1 to 0.
    error_low, error_high : float
        Smoothed one-step prediction error (-) below which trust is full and above which it is 0.
    error_smoothing : float
        Weight ``a`` of the newest error in the exponential average, in (0, 1].
    min_span : float
        Floor (-) of each feature's span as a fraction of its largest magnitude in training,
        in [0, 1]; 0 for the spread alone.
    """

    enabled: bool = True
    range_margin: float = 0.05
    range_fade: float = 0.25
    error_low: float = 0.08
    error_high: float = 0.25
    error_smoothing: float = 0.2
    min_span: float = 0.2

    def __post_init__(self) -> None:
        require_nonnegative(self, "range_margin", "error_low")
        require_positive(self, "range_fade", "error_high", "error_smoothing")
        if self.error_high <= self.error_low:
            raise ParameterError("TrustConfig.error_high must exceed error_low")
        if self.error_smoothing > 1.0:
            raise ParameterError("TrustConfig.error_smoothing must be in (0, 1]")
        if not 0.0 <= self.min_span <= 1.0:
            raise ParameterError(f"TrustConfig.min_span must be in [0, 1], got {self.min_span!r}")


class CorrectionTrust:
    """Trust in a residual model's correction, from its training range and its recent predictions.

    Parameters
    ----------
    A, B, Cx : numpy.ndarray
        The model's lifted dynamics ``z+ = A z + B u`` and the map ``x = Cx z`` back to the features.
    x_min, x_max : numpy.ndarray, shape (nx,)
        Training range of the features.
    config : TrustConfig
        Thresholds.

    Attributes
    ----------
    steps : int
        Steps judged since :meth:`reset`.
    faded : dict of str to int
        Steps with trust below 1, by cause (``"range"``, ``"error"``).
    trust : float
        The last trust.
    """

    def __init__(
        self,
        A: np.ndarray,
        B: np.ndarray,
        Cx: np.ndarray,
        x_min: np.ndarray,
        x_max: np.ndarray,
        config: TrustConfig,
    ) -> None:
        self._A, self._B, self._Cx = A, B, Cx
        self._x_min = np.asarray(x_min, dtype=float)
        self._x_max = np.asarray(x_max, dtype=float)
        size = np.maximum(np.abs(self._x_min), np.abs(self._x_max))
        span = np.maximum(self._x_max - self._x_min, config.min_span * size)
        self._inv_span = 1.0 / np.where(span > 1e-9, span, 1e-9)
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Forget the last prediction and the counts."""
        self._predicted: np.ndarray | None = None
        self._error = 0.0
        self.steps = 0
        self.faded = {"range": 0, "error": 0}
        self.trust = 1.0
        self._trust_sum = 0.0

    @property
    def mean(self) -> float:
        """Mean trust over the steps judged since :meth:`reset` (1 before any)."""
        return self._trust_sum / self.steps if self.steps else 1.0

    def judge(self, x: np.ndarray) -> float:
        """Trust (0-1) of this step's correction, for the features ``x`` (shape (nx,)) seen now."""
        cfg = self.config
        if self._predicted is not None:
            e = float(np.max(np.abs(x - self._predicted) * self._inv_span))
            self._error += cfg.error_smoothing * (e - self._error)
        w_range = float(self.range_trust(x))
        w_error = min(max((cfg.error_high - self._error) / (cfg.error_high - cfg.error_low), 0.0), 1.0)
        self.steps += 1
        if w_range < 1.0:
            self.faded["range"] += 1
        if w_error < 1.0:
            self.faded["error"] += 1
        self.trust = min(w_range, w_error) if cfg.enabled else 1.0
        self._trust_sum += self.trust
        return self.trust

    def range_trust(self, x: np.ndarray) -> np.ndarray:
        """The range part of the trust of features ``x``, shape (..., nx) -> (...,): 1 inside the
        training range and its margin, falling to 0 over the fade."""
        cfg = self.config
        outside = np.maximum(np.maximum(self._x_min - x, x - self._x_max), 0.0) * self._inv_span
        return np.clip(1.0 - (np.max(outside, axis=-1) - cfg.range_margin) / cfg.range_fade, 0.0, 1.0)

    def expect(self, z: np.ndarray, u: np.ndarray) -> None:
        """Remember the model's prediction of the next features from lifted state ``z`` and input ``u``."""
        self._predicted = self._Cx @ (self._A @ z + self._B @ u)

    @property
    def error(self) -> float:
        """The smoothed one-step prediction error (fraction of the training span)."""
        return self._error
