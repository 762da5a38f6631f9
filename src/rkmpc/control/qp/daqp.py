"""DAQP, the dense dual active-set solver, behind :class:`~rkmpc.control.qp.base.DenseQP`."""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dpotrf as _dpotrf
from scipy.linalg.lapack import dtrtri as _dtrtri

from rkmpc.control.qp.base import DenseQP, QPResult

__all__ = ["DaqpQP"]


class DaqpQP(DenseQP):
    """Dense dual active-set solver DAQP (``daqp.Model``), warm-started by active set.

    Parameters
    ----------
    max_iterations : int
        Iteration budget per solve.
    factorize : bool
        Factorise ``H`` here instead of in DAQP. Meant for problems whose
        Hessian changes at every solve: DAQP's own refactorisation (a plain C
        Cholesky factorisation and inversion) dominates the solve time of a
        small dense QP, while LAPACK does the same work several times faster.
        With ``H = R' R`` (``R`` upper triangular) and ``y = R x``, DAQP is
        handed the equivalent problem ``min 0.5 y'y + (R^-T f)' y`` subject to
        ``lb <= R^-1 y <= ub`` and ``lbA <= A R^-1 y <= ubA``, with an identity
        Hessian that it never refactorises. DAQP itself solves exactly this
        problem (its constraint rows are ``R^-1`` and ``A R^-1`` in both cases,
        normalised the same way), so the iterates, the active sets and the
        solution agree up to rounding. Without it (the default) the Hessian
        is given to DAQP as is, which suits a Hessian fixed at set-up.
    """

    def __init__(self, max_iterations: int = 200, factorize: bool = False) -> None:
        super().__init__(max_iterations)
        import daqp

        self._model = daqp.Model()
        self.factorize = bool(factorize)
        # Factorised mode: the fixed constraint matrix, R^-1, DAQP's constraint
        # rows [R^-1; A R^-1] and linear term R^-T f.
        self._A = np.zeros((0, 0))
        self._rinv = np.zeros((0, 0))
        self._rows = np.zeros((0, 0))
        self._f = np.zeros(0)
        self._g = np.zeros(0)
        self._nonconvex = False

    def _setup_solver(self, H: np.ndarray, f: np.ndarray, A: np.ndarray) -> None:
        n = self._n
        if self.factorize:
            self._A = np.array(A, dtype=float).reshape(-1, n)
            self._rows = np.zeros((n + self._A.shape[0], n))
            self._f = np.array(f, dtype=float)
            self._g = np.zeros(n)
            self._factor(H)
            self._model.setup(np.eye(n), self._g, self._rows, self._upper, self._lower)
        else:
            self._model.setup(
                np.ascontiguousarray(H, dtype=float),
                np.ascontiguousarray(f, dtype=float),
                np.ascontiguousarray(A, dtype=float),
                self._upper,
                self._lower,
            )
        self._model.settings = {"iter_limit": self.max_iterations}

    def _factor(self, H: np.ndarray) -> None:
        """``R^-1`` of ``H = R' R``, DAQP's constraint rows and its linear term (factorised mode)."""
        # LAPACK reads a Fortran-ordered lower triangle: that of H.T, i.e. the upper triangle of
        # the C-ordered H, the one DAQP itself reads. The factor L = R' comes back in Fortran
        # order, so the transpose of its inverse is R^-1 in C order without a copy.
        L, info = _dpotrf(np.asarray(H, dtype=float).T, lower=1, clean=1)
        self._nonconvex = info != 0
        if self._nonconvex:
            return
        Linv, _ = _dtrtri(L, lower=1, overwrite_c=1)
        self._rinv = Linv.T
        n = self._n
        if self._A.shape[0]:
            self._rows[:n] = self._rinv
            np.dot(self._A, self._rinv, out=self._rows[n:])
        else:
            self._rows = self._rinv
        np.dot(self._f, self._rinv, out=self._g)

    def _update_solver(
        self, H: np.ndarray | None, f: np.ndarray | None, A: np.ndarray | None, bounds_changed: bool
    ) -> None:
        n = self._n
        bu = self._upper if bounds_changed else None
        bl = self._lower if bounds_changed else None
        if not self.factorize:
            self._model.update(
                H=None if H is None else np.ascontiguousarray(H, dtype=float),
                f=None if f is None else np.ascontiguousarray(f, dtype=float),
                A=None if A is None else np.ascontiguousarray(A, dtype=float),
                bupper=bu,
                blower=bl,
            )
            return
        if f is not None:
            self._f[:] = f
        if A is not None:
            self._A[:] = A
            if H is None:  # the constraint rows are A R^-1: new rows with the factor held
                if not self._nonconvex and self._A.shape[0]:
                    np.dot(self._A, self._rinv, out=self._rows[n:])
                    if f is not None:
                        np.dot(self._f, self._rinv, out=self._g)
                    self._model.update(A=self._rows, f=self._g, bupper=self._upper, blower=self._lower)
                return
        if H is not None:
            self._factor(H)
            if not self._nonconvex:
                self._model.update(A=self._rows, f=self._g, bupper=self._upper, blower=self._lower)
            return
        if f is not None and not self._nonconvex:
            np.dot(self._f, self._rinv, out=self._g)
        self._model.update(f=None if f is None else self._g, bupper=bu, blower=bl)

    def solve(self) -> QPResult:
        if self.factorize and self._nonconvex:
            return QPResult(x=np.full(self._n, np.nan), solved=False, status="nonconvex", iterations=0)
        y, _fval, exitflag, info = self._model.solve()
        x = self._rinv @ y if self.factorize else np.asarray(y, dtype=float)
        return QPResult(
            x=x,
            solved=bool(exitflag >= 1),
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
