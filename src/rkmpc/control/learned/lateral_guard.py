"""The worst case no worse than the baseline's: a constraint on the residual MPC's lateral deviations.

The residual MPC of ``rkmpc`` chooses a correction ``dU`` of the LMPC's plan that minimises a
weighted sum of the predicted deviations (:mod:`rkmpc.control.learned.rkmpc`). A sum can trade a
larger deviation at one step of the horizon for smaller ones at the others: in the tightest corners,
where the LMPC's own deviation peaks, that is the lateral maximum. :class:`LateralGuard` adds to the
residual QP the constraint that, as the learned model predicts them, the lateral deviations of the
corrected plan stay at every step of the horizon within the largest lateral deviation of the
uncorrected plan (the LMPC's plan under the same model), plus a margin:

``|n_k' (e0 + G dU)_k| <= max_j |n_j' e0_j| + margin``, ``k = 1..N``,

with ``n_k`` the reference's normal at step ``k`` (the lateral direction), ``e0`` the predicted
deviations of the LMPC's plan and ``G`` their sensitivity to the correction. ``dU = 0`` always
satisfies it, so the residual QP stays feasible. A step whose solution sits on the constraint is a
step the guard acted on; the controller counts them (``lateral_guard_steps``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_bool

__all__ = ["LateralGuard", "LateralGuardConfig"]


@dataclass(frozen=True)
class LateralGuardConfig:
    """Settings of :class:`LateralGuard`.

    Parameters
    ----------
    enabled : bool
        Whether the constraint is posed.
    margin_wheelbases : float
        Margin (in wheelbases, >= 0) above the uncorrected plan's largest lateral deviation.
    """

    enabled: bool = False
    margin_wheelbases: float = 0.02

    def __post_init__(self) -> None:
        require_bool(self, "enabled")
        m = self.margin_wheelbases
        if not (isinstance(m, int | float) and not isinstance(m, bool) and np.isfinite(m) and m >= 0.0):
            raise ParameterError(f"LateralGuardConfig.margin_wheelbases must be finite and >= 0, got {m!r}")


class LateralGuard:
    """The lateral-deviation constraint of the residual QP, step by step (module docstring).

    Parameters
    ----------
    horizon : int
        Steps ``N`` of the prediction.
    wheelbase : float
        The car's wheelbase (m): the margin's unit.
    config : LateralGuardConfig
        Margin and switch.
    """

    def __init__(self, horizon: int, wheelbase: float, config: LateralGuardConfig) -> None:
        self.horizon = horizon
        self.margin = config.margin_wheelbases * wheelbase
        self.config = config
        self._n = np.zeros((horizon, 2))
        self.rows = np.zeros((horizon if config.enabled else 0, 2 * horizon))
        self.lower = np.zeros(self.rows.shape[0])
        self.upper = np.zeros(self.rows.shape[0])
        self._free = np.zeros(horizon)
        self._bound = 0.0
        self.reset()

    def reset(self) -> None:
        """Forget the count."""
        #: Steps whose corrected plan sat on the constraint.
        self.steps = 0

    def pose(self, theta: np.ndarray, e0: np.ndarray, sensitivity: np.ndarray) -> None:
        """Set the constraint of this step.

        Parameters
        ----------
        theta : numpy.ndarray
            Reference headings of steps ``1..N`` (rad), shape (N,).
        e0 : numpy.ndarray
            Predicted deviations ``[x, y, theta]`` of the uncorrected plan, shape (3N,).
        sensitivity : numpy.ndarray
            Their sensitivity to the correction, shape (3N, 2N).
        """
        if not self.config.enabled:
            return
        n = self._n
        n[:, 0] = -np.sin(theta)
        n[:, 1] = np.cos(theta)
        free = n[:, 0] * e0[0::3] + n[:, 1] * e0[1::3]
        np.multiply(n[:, :1], sensitivity[0::3], out=self.rows)
        self.rows += n[:, 1:] * sensitivity[1::3]
        bound = float(np.max(np.abs(free))) + self.margin
        np.subtract(-bound, free, out=self.lower)
        np.subtract(bound, free, out=self.upper)
        self._free = free
        self._bound = bound

    def judge(self, correction: np.ndarray) -> None:
        """Count the step when the solution ``correction`` (2N,) sits on the constraint."""
        if not self.config.enabled:
            return
        lateral = self._free + self.rows @ correction
        if float(np.max(np.abs(lateral))) >= self._bound - 1e-6 * max(self._bound, 1e-9):
            self.steps += 1
