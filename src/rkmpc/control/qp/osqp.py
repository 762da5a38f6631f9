"""OSQP, the sparse ADMM solver, behind :class:`~rkmpc.control.qp.base.DenseQP`."""

from __future__ import annotations

from typing import Any

import numpy as np

from rkmpc.control.qp.base import DenseQP, QPResult

__all__ = ["OsqpQP"]


class OsqpQP(DenseQP):
    """OSQP (ADMM, sparse) on the same problem, warm-started from the previous iterate.

    The dense ``H`` is stored with a full upper-triangular pattern so that its
    values can be updated in place.

    Parameters
    ----------
    max_iterations : int
        ADMM iteration budget per solve.
    eps : float
        Absolute and relative tolerance.
    factorize : bool
        Accepted for interchangeability with :class:`DaqpQP` and ignored: OSQP
        always factorises its own KKT matrix.
    """

    def __init__(self, max_iterations: int = 4000, eps: float = 1e-5, factorize: bool = False) -> None:
        super().__init__(max_iterations)
        self.eps = eps
        self._solver: Any = None
        self._triu: tuple[np.ndarray, np.ndarray] = (np.zeros(0, int), np.zeros(0, int))
        self._a_pattern = np.zeros(0, int)

    def _setup_solver(self, H: np.ndarray, f: np.ndarray, A: np.ndarray) -> None:
        import osqp
        from scipy import sparse

        n = self._n
        rows, cols = np.triu_indices(n)
        # Column-major order of the upper triangle, the order CSC stores it in.
        order = np.lexsort((rows, cols))
        self._triu = (rows[order], cols[order])
        P = sparse.csc_matrix((np.asarray(H)[self._triu], self._triu), shape=(n, n))
        # [I; A] with A stored densely (every entry in the pattern), so its values can change.
        A = np.asarray(A, dtype=float).reshape(-1, n)
        dense = np.vstack([np.eye(n), A])
        pattern = np.vstack([np.eye(n), np.ones_like(A)]) != 0
        Acon = sparse.csc_matrix((dense[pattern.nonzero()], pattern.nonzero()), shape=dense.shape)
        Acon.sort_indices()
        rows, cols = pattern.nonzero()
        order = np.lexsort((rows, cols))
        self._a_pattern = cols[order] * dense.shape[0] + rows[order]
        self._solver = osqp.OSQP()
        self._solver.setup(
            P,
            np.asarray(f, dtype=float),
            Acon,
            self._lower,
            self._upper,
            verbose=False,
            warm_starting=True,
            polishing=True,
            eps_abs=self.eps,
            eps_rel=self.eps,
            max_iter=self.max_iterations,
        )

    def _update_solver(
        self, H: np.ndarray | None, f: np.ndarray | None, A: np.ndarray | None, bounds_changed: bool
    ) -> None:
        n = self._n
        kwargs: dict[str, np.ndarray] = {}
        if H is not None:
            kwargs["Px"] = np.asarray(H)[self._triu]
        if f is not None:
            kwargs["q"] = np.asarray(f, dtype=float)
        if bounds_changed:
            kwargs["l"] = self._lower
            kwargs["u"] = self._upper
        if A is not None:  # the values of [I; A] in the (dense) pattern set up
            dense = np.vstack([np.eye(n), np.asarray(A, dtype=float)])
            kwargs["Ax"] = dense.T.reshape(-1)[self._a_pattern]
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
