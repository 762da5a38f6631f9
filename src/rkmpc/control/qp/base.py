"""The dense-QP interface: :class:`DenseQP` and :class:`QPResult`."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

__all__ = ["QP_REASONS", "DenseQP", "QPResult"]


@dataclass(frozen=True)
class QPResult:
    """Outcome of one QP solve.

    Parameters
    ----------
    x : numpy.ndarray
        Primal solution, shape (n,); meaningless when ``solved`` is False.
    solved : bool
        Whether the solver reported an optimal solution.
    status : str
        The solver's status, in words.
    iterations : int
        Iterations the solver used.
    """

    x: np.ndarray
    solved: bool
    status: str
    iterations: int

    @property
    def reason(self) -> str:
        """The outcome as a controller status (:data:`rkmpc.control.base.STATUSES`).

        ``"ok"`` when solved with a finite solution; ``"infeasible"`` and ``"iteration_limit"``
        where the solver says so; ``"numerical"`` for every other failure (see
        :data:`QP_REASONS`), a non-finite "solution" included.
        """
        if self.solved:
            return "ok" if bool(np.isfinite(self.x).all()) else "numerical"
        return QP_REASONS[self.status] if self.status in QP_REASONS else "numerical"


class DenseQP(ABC):
    """Common interface of the QP backends.

    :meth:`setup` and :meth:`update` keep the stacked bounds ``[lb; lbA]`` and ``[ub; ubA]`` (in
    place, so a backend may hold them); a backend builds and updates its solver in
    :meth:`_setup_solver` and :meth:`_update_solver`.

    Parameters
    ----------
    max_iterations : int
        Iteration budget per solve; a solve that needs more reports failure.
    """

    def __init__(self, max_iterations: int = 200) -> None:
        if max_iterations < 1:
            raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
        self.max_iterations = max_iterations
        self._is_setup = False
        # The number of variables and the stacked bounds [lb; lbA] and [ub; ubA] the backends share.
        self._n = 0
        self._lower = np.zeros(0)
        self._upper = np.zeros(0)

    @property
    def is_setup(self) -> bool:
        """Whether :meth:`setup` has been called."""
        return self._is_setup

    def setup(
        self,
        H: np.ndarray,
        f: np.ndarray,
        lb: np.ndarray,
        ub: np.ndarray,
        A: np.ndarray,
        lbA: np.ndarray,
        ubA: np.ndarray,
    ) -> None:
        """Build the solver workspace (called once).

        ``min 0.5 x' H x + f' x`` subject to ``lb <= x <= ub`` and ``lbA <= A x <= ubA``.
        """
        self._n = int(np.shape(H)[0])
        self._lower = np.ascontiguousarray(np.concatenate([lb, lbA]), dtype=float)
        self._upper = np.ascontiguousarray(np.concatenate([ub, ubA]), dtype=float)
        self._setup_solver(H, f, A)
        self._is_setup = True

    def update(
        self,
        H: np.ndarray | None = None,
        f: np.ndarray | None = None,
        lb: np.ndarray | None = None,
        ub: np.ndarray | None = None,
        lbA: np.ndarray | None = None,
        ubA: np.ndarray | None = None,
        A: np.ndarray | None = None,
    ) -> None:
        """Replace numbers of the problem (``A`` too, its shape kept); shapes must stay the same."""
        n = self._n
        if lb is not None:
            self._lower[:n] = lb
        if lbA is not None:
            self._lower[n:] = lbA
        if ub is not None:
            self._upper[:n] = ub
        if ubA is not None:
            self._upper[n:] = ubA
        bounds_changed = any(b is not None for b in (lb, ub, lbA, ubA))
        self._update_solver(H, f, A, bounds_changed)

    @abstractmethod
    def _setup_solver(self, H: np.ndarray, f: np.ndarray, A: np.ndarray) -> None:
        """Build the backend's workspace; ``_n``, ``_lower`` and ``_upper`` are set."""

    @abstractmethod
    def _update_solver(
        self, H: np.ndarray | None, f: np.ndarray | None, A: np.ndarray | None, bounds_changed: bool
    ) -> None:
        """Hand the backend the numbers that changed (``_lower`` and ``_upper`` are up to date)."""

    @abstractmethod
    def solve(self) -> QPResult:
        """Solve the current problem, warm-started from the previous solve."""


#: Controller status of a failed QP by the solver's status (DAQP's words and OSQP's); others are
#: ``"numerical"``. A time limit is never set here; should a solver report one, it is a budget.
QP_REASONS: dict[str, str] = {
    "infeasible": "infeasible",
    "iteration limit": "iteration_limit",
    "time limit": "iteration_limit",
    "primal infeasible": "infeasible",
    "primal infeasible inaccurate": "infeasible",
    "dual infeasible": "infeasible",
    "dual infeasible inaccurate": "infeasible",
    "maximum iterations reached": "iteration_limit",
    "run time limit reached": "iteration_limit",
}
