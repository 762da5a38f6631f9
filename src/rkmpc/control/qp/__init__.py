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

from collections.abc import Callable

from rkmpc.control.qp.base import QP_REASONS, DenseQP, QPResult
from rkmpc.control.qp.daqp import DaqpQP
from rkmpc.control.qp.osqp import OsqpQP
from rkmpc.core.registry import Registry

__all__ = ["QP_REASONS", "QP_SOLVERS", "DaqpQP", "DenseQP", "OsqpQP", "QPResult", "make_qp"]


#: QP backends by name.
QP_SOLVERS: Registry[Callable[..., DenseQP]] = Registry("QP solver", {"daqp": DaqpQP, "osqp": OsqpQP})


def make_qp(name: str, *, max_iterations: int, factorize: bool = False) -> DenseQP:
    """Build a QP backend by name (``"daqp"`` or ``"osqp"``).

    Parameters
    ----------
    name : str
        Backend name, a key of :data:`QP_SOLVERS`.
    max_iterations : int
        Iteration budget per solve.
    factorize : bool
        Factorise the Hessian outside the solver (see :class:`DaqpQP`; OSQP ignores it).
    """
    return QP_SOLVERS[name](max_iterations=max_iterations, factorize=factorize)
