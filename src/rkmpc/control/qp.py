"""A small dense-QP layer over real solvers, set up once and updated in place.

Problems have the form::

    minimise    0.5 x' H x + f' x
    subject to  lb  <= x   <= ub
                lbA <= A x <= ubA

``A`` is fixed at set-up (its sparsity and values); ``H``, ``f`` and all bounds
may change between solves. Each backend keeps its workspace between calls and
warm-starts from the previous active set or iterate.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


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


class DenseQP(ABC):
    """Common interface of the QP backends.

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

    @property
    def is_setup(self) -> bool:
        """Whether :meth:`setup` has been called."""
        return self._is_setup

    @abstractmethod
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
        """Build the solver workspace (called once)."""

    @abstractmethod
    def update(
        self,
        H: np.ndarray | None = None,
        f: np.ndarray | None = None,
        lb: np.ndarray | None = None,
        ub: np.ndarray | None = None,
        lbA: np.ndarray | None = None,
        ubA: np.ndarray | None = None,
    ) -> None:
        """Replace numbers of the problem; shapes must stay the same."""

    @abstractmethod
    def solve(self) -> QPResult:
        """Solve the current problem, warm-started from the previous solve."""


class DaqpQP(DenseQP):
    """Dense dual active-set solver DAQP (``daqp.Model``), warm-started by active set."""

    def __init__(self, max_iterations: int = 200) -> None:
        super().__init__(max_iterations)
        import daqp

        self._model = daqp.Model()
        self._n = 0
        self._bu = np.zeros(0)
        self._bl = np.zeros(0)

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
        self._n = int(np.shape(H)[0])
        self._bu = np.ascontiguousarray(np.concatenate([ub, ubA]), dtype=float)
        self._bl = np.ascontiguousarray(np.concatenate([lb, lbA]), dtype=float)
        self._model.setup(
            np.ascontiguousarray(H, dtype=float),
            np.ascontiguousarray(f, dtype=float),
            np.ascontiguousarray(A, dtype=float),
            self._bu,
            self._bl,
        )
        self._model.settings = {"iter_limit": self.max_iterations}
        self._is_setup = True

    def update(
        self,
        H: np.ndarray | None = None,
        f: np.ndarray | None = None,
        lb: np.ndarray | None = None,
        ub: np.ndarray | None = None,
        lbA: np.ndarray | None = None,
        ubA: np.ndarray | None = None,
    ) -> None:
        n = self._n
        if ub is not None:
            self._bu[:n] = ub
        if ubA is not None:
            self._bu[n:] = ubA
        if lb is not None:
            self._bl[:n] = lb
        if lbA is not None:
            self._bl[n:] = lbA
        bounds_changed = any(b is not None for b in (lb, ub, lbA, ubA))
        self._model.update(
            H=None if H is None else np.ascontiguousarray(H, dtype=float),
            f=None if f is None else np.ascontiguousarray(f, dtype=float),
            bupper=self._bu if bounds_changed else None,
            blower=self._bl if bounds_changed else None,
        )

    def solve(self) -> QPResult:
        x, _fval, exitflag, info = self._model.solve()
        solved = exitflag >= 1
        return QPResult(
            x=np.asarray(x, dtype=float),
            solved=bool(solved),
            status=_DAQP_STATUS.get(int(exitflag), f"exitflag {exitflag}"),
            iterations=int(info["iterations"]),
        )


_DAQP_STATUS = {
    1: "optimal",
    2: "soft optimal",
    -1: "infeasible",
    -2: "cycling",
    -3: "unbounded",
    -4: "iteration limit",
    -5: "nonconvex",
    -6: "initial working set overdetermined",
    -7: "time limit",
}


class OsqpQP(DenseQP):
    """OSQP (ADMM, sparse) on the same problem, warm-started from the previous iterate.

    The dense ``H`` is stored with a full upper-triangular pattern so that its
    values can be updated in place.
    """

    def __init__(self, max_iterations: int = 4000, eps: float = 1e-5) -> None:
        super().__init__(max_iterations)
        self.eps = eps
        self._solver: Any = None
        self._triu: tuple[np.ndarray, np.ndarray] = (np.zeros(0, int), np.zeros(0, int))
        self._l = np.zeros(0)
        self._u = np.zeros(0)
        self._n = 0

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
        import osqp
        from scipy import sparse

        n = int(np.shape(H)[0])
        self._n = n
        rows, cols = np.triu_indices(n)
        # Column-major order of the upper triangle, the order CSC stores it in.
        order = np.lexsort((rows, cols))
        self._triu = (rows[order], cols[order])
        P = sparse.csc_matrix((np.asarray(H)[self._triu], self._triu), shape=(n, n))
        Acon = sparse.vstack([sparse.identity(n, format="csc"), sparse.csc_matrix(A)], format="csc")
        self._l = np.concatenate([lb, lbA]).astype(float)
        self._u = np.concatenate([ub, ubA]).astype(float)
        self._solver = osqp.OSQP()
        self._solver.setup(
            P,
            np.asarray(f, dtype=float),
            Acon,
            self._l,
            self._u,
            verbose=False,
            warm_starting=True,
            polishing=True,
            eps_abs=self.eps,
            eps_rel=self.eps,
            max_iter=self.max_iterations,
        )
        self._is_setup = True

    def update(
        self,
        H: np.ndarray | None = None,
        f: np.ndarray | None = None,
        lb: np.ndarray | None = None,
        ub: np.ndarray | None = None,
        lbA: np.ndarray | None = None,
        ubA: np.ndarray | None = None,
    ) -> None:
        n = self._n
        if lb is not None:
            self._l[:n] = lb
        if lbA is not None:
            self._l[n:] = lbA
        if ub is not None:
            self._u[:n] = ub
        if ubA is not None:
            self._u[n:] = ubA
        kwargs: dict[str, np.ndarray] = {}
        if H is not None:
            kwargs["Px"] = np.asarray(H)[self._triu]
        if f is not None:
            kwargs["q"] = np.asarray(f, dtype=float)
        if any(b is not None for b in (lb, ub, lbA, ubA)):
            kwargs["l"] = self._l
            kwargs["u"] = self._u
        if kwargs:
            self._solver.update(**kwargs)

    def solve(self) -> QPResult:
        res = self._solver.solve(raise_error=False)
        status = str(res.info.status)
        solved = status in ("solved", "solved inaccurate")
        x = res.x if res.x is not None else np.full(self._n, np.nan)
        return QPResult(
            x=np.asarray(x, dtype=float), solved=solved, status=status, iterations=int(res.info.iter)
        )


#: QP backends by name.
QP_SOLVERS: dict[str, Callable[..., DenseQP]] = {"daqp": DaqpQP, "osqp": OsqpQP}


def make_qp(name: str, **options: int | float) -> DenseQP:
    """Build a QP backend by name (``"daqp"`` or ``"osqp"``).

    Parameters
    ----------
    name : str
        Backend name, a key of :data:`QP_SOLVERS`.
    **options
        Passed to the backend (for example ``max_iterations``).
    """
    try:
        factory = QP_SOLVERS[name]
    except KeyError:
        raise ValueError(f"unknown QP solver {name!r}; known: {sorted(QP_SOLVERS)}") from None
    return factory(**options)
