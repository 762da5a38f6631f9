"""Dynamic single-track NMPC as an acados real-time iteration (``nmpc-acados-dynamic``).

The model, cost, horizon, bounds and state estimate are those of
:class:`rkmpc.control.nonlinear.nmpc.DynamicNMPC` (nominal plant parameters, Pacejka
tyres, speed loop and steering-servo lag, the wheel angle estimated from the
servo model when it is not measured); the OCP is posed and solved as in
:mod:`rkmpc.control.nonlinear.acados`. As in :class:`DynamicNMPC`, the RTI uses
the Gauss-Newton Hessian unless the config asks for ``hessian="exact"`` (the
exact Hessian of the Lagrangian, mirrored to be positive definite); both track
alike on every track here, the exact one costs about twice the time.
"""

from __future__ import annotations

from rkmpc.control.nonlinear.acados import AcadosKinematicNMPC
from rkmpc.control.nonlinear.nmpc import DynamicNMPC

__all__ = ["AcadosDynamicNMPC"]


class AcadosDynamicNMPC(AcadosKinematicNMPC, DynamicNMPC):
    """Dynamic single-track NMPC solved by one acados real-time iteration per period.

    States ``[x, y, theta, v, beta, r, delta_w]`` plus the previous command,
    inputs ``[v_cmd, delta_cmd]``.

    Parameters
    ----------
    reference, vehicle
        As :class:`DynamicNMPC`: the path and speed profile, and the nominal car (whose
        ``blend_speed_high`` is the speed floor of the model's slip denominators).
    config : NMPCConfig, optional
        Weights, horizon, period (s), RK4 sub-steps (2 by default) and Hessian
        (Gauss-Newton by default).
    qp_solver : str
        One of :data:`rkmpc.control.nonlinear.acados.QP_SOLVERS`.
    cache_dir : path, optional
        Root of the generated solvers.

    Raises
    ------
    ImportError
        When acados or cython is not installed.
    """

    name = "nmpc-acados-dynamic"
    default_hessian = "gauss-newton"
    model_tag = "dyn"
