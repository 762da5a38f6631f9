"""Settings of the nonlinear MPCs (:class:`NMPCConfig`), without CasADi: a car file can hold them."""

from __future__ import annotations

from dataclasses import dataclass

from rkmpc.control.tracking import TrackingCost, check_iterations
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_choice, require_positive

__all__ = ["HESSIANS", "SOLVERS", "NMPCConfig"]

#: NLP solvers :class:`NMPCConfig` accepts.
SOLVERS = ("ipopt", "sqpmethod")
#: Hessian choices of :class:`NMPCConfig`.
HESSIANS = ("exact", "gauss-newton", "limited-memory")


@dataclass(frozen=True)
class NMPCConfig(TrackingCost):
    """Horizon, weights and solver of the nonlinear MPCs.

    The horizon, period, weights and their defaults are those of
    :class:`rkmpc.control.tracking.TrackingCost`, shared with the LMPC, so the
    NMPC and the LMPC differ only in the model.

    Parameters
    ----------
    solver : str
        ``"ipopt"`` (interior point, solved to convergence) or ``"sqpmethod"``
        (SQP with the ``qrqp`` QP solver; with ``max_iterations=1`` one
        Newton-type step per period, like a real-time iteration).
    max_iterations : int
        Iteration budget per step; IPOPT's ``max_iter``, or the SQP iterations.
        An IPOPT solve that reaches it falls back.
    max_cpu_time : float or None
        IPOPT's CPU-time budget per step (s), or None (default) for none. A
        wall-clock budget makes the result depend on how busy the machine is:
        opt in for real-time use on a car only; the real-time question is
        answered by the benchmarks.
    warm_start : bool
        Warm-start every solve from the shifted previous solution, primal and
        dual (for IPOPT with ``warm_start_init_point``).
    tolerance : float
        IPOPT's ``tol`` (and the SQP's ``tol_pr``/``tol_du``).
    substeps : int or None
        RK4 steps per control period; None for the model's default (1 for the
        kinematic model, 2 for the dynamic one).
    hessian : str or None
        Hessian of the Lagrangian: ``"exact"``; ``"gauss-newton"``, the
        Hessian of the (quadratic) cost alone, which drops the curvature of
        the model and costs nothing to evaluate; ``"limited-memory"``
        (L-BFGS); or None for the model's default
        (exact for the kinematic model, Gauss-Newton for the dynamic one,
        whose exact Hessian dominates the solve time).
    """

    solver: str = "ipopt"
    max_iterations: int = 50
    max_cpu_time: float | None = None
    warm_start: bool = True
    tolerance: float = 1e-6
    substeps: int | None = None
    hessian: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        require_positive(self, "tolerance")
        if self.max_cpu_time is not None:
            require_positive(self, "max_cpu_time")
        require_choice(self, "solver", SOLVERS)
        check_iterations(self, self.max_iterations)
        if self.hessian is not None:
            require_choice(self, "hessian", HESSIANS)
        if self.substeps is not None and self.substeps < 1:
            raise ParameterError(f"NMPCConfig.substeps must be >= 1 or None, got {self.substeps}")
