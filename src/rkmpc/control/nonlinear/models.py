"""CasADi prediction models of the nonlinear MPCs (:mod:`rkmpc.control.nonlinear.nmpc`).

Two continuous-time models, both with inputs ``u = [v_cmd, delta_cmd]``:

* :func:`kinematic_ode`, the paper's kinematic bicycle (Eq. 1), states
  ``[x, y, theta]``, in which the commanded speed and angle act at once;
* :func:`dynamic_ode`, the nominal dynamic single-track model of the plant
  (:mod:`rkmpc.vehicle.plants.dynamic`), states ``[x, y, theta, v, beta, r, delta_w]``,
  with Pacejka lateral forces (or the tyre models given, :func:`tyre_force`), longitudinal
  load transfer, a first-order speed loop and a first-order steering servo. The actuator rate and acceleration
  clips of the plant are left out (the MPC bounds the steering rate itself),
  and instead of the plant's kinematic blend the speed in every denominator is
  floored by a smooth maximum, which keeps the model smooth and well defined as ``v -> 0``.

:func:`rk4_map` turns either into the discrete map of one control period.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import casadi as ca

from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.params import PacejkaParams, VehicleParams
from rkmpc.vehicle.tyres import LinearTyre, PacejkaTyre, TyreModel

__all__ = ["dynamic_ode", "kinematic_ode", "pacejka", "rk4_map", "tyre_force"]


def kinematic_ode(wheelbase: float) -> Any:
    """Kinematic bicycle ``f(x, u)`` as a CasADi SX function.

    Parameters
    ----------
    wheelbase : float
        ``L = lf + lr`` (m).

    Returns
    -------
    casadi.Function
        ``f(x[3], u[2]) -> xdot[3]`` with ``xdot = v cos th``, ``ydot = v sin th``,
        ``thdot = v tan(delta) / L``.
    """
    x = ca.SX.sym("x", 3)
    u = ca.SX.sym("u", 2)
    v, delta = u[0], u[1]
    th = x[2]
    rhs = ca.vertcat(v * ca.cos(th), v * ca.sin(th), v * ca.tan(delta) / wheelbase)
    return ca.Function("kinematic_ode", [x, u], [rhs], ["x", "u"], ["xdot"])


def pacejka(tyre: PacejkaParams, alpha: Any, load: Any) -> Any:
    """Simplified magic formula ``load * D * sin(C atan(B a - E (B a - atan(B a))))``; ``load = mu Fz``."""
    ba = tyre.B * alpha
    return load * tyre.D * ca.sin(tyre.C * ca.atan(ba - tyre.E * (ba - ca.atan(ba))))


#: CasADi force law of each tyre model: ``law(tyre, alpha, load)`` with ``load = mu Fz``.
_TYRE_FORCES: dict[type, Callable[[Any, Any, Any], Any]] = {
    PacejkaTyre: lambda tyre, alpha, load: pacejka(tyre.params, alpha, load),
    LinearTyre: lambda tyre, alpha, load: load * tyre.stiffness_per_load * alpha,
}


def tyre_force(tyre: TyreModel, alpha: Any, load: Any) -> Any:
    """Lateral force (N) of ``tyre`` at slip angle ``alpha`` (rad) under ``load = mu Fz`` (N), in CasADi.

    Raises
    ------
    ParameterError
        For a tyre model without a CasADi force law.
    """
    law = _TYRE_FORCES.get(type(tyre))
    if law is None:
        known = ", ".join(t.__name__ for t in _TYRE_FORCES)
        raise ParameterError(f"no CasADi force law for the tyre model {type(tyre).__name__} (known: {known})")
    return law(tyre, alpha, load)


def dynamic_ode(
    params: VehicleParams, min_speed: float = 1.0, tyres: tuple[TyreModel, TyreModel] | None = None
) -> Any:
    """Nominal dynamic single-track model ``f(x, u)`` as a CasADi SX function.

    Parameters
    ----------
    params : VehicleParams
        Nominal car parameters (mass, inertia, axle distances, tyres, friction,
        servo and speed-loop time constants).
    min_speed : float
        Floor (m/s) of the speed in the slip-angle and side-slip denominators
        (a smooth maximum, ``0.5 (v + v0 + sqrt((v - v0)^2 + (0.2 v0)^2))``).
        It bounds the stiffness of the model at low speed, so that RK4 with a
        few sub-steps per control period stays stable.
    tyres : tuple of TyreModel, optional
        Front and rear tyre models (their force laws take ``mu Fz``) instead of the Pacejka
        coefficients of ``params``.

    Returns
    -------
    casadi.Function
        ``f(x[7], u[2]) -> xdot[7]`` with ``x = [x, y, theta, v, beta, r, delta_w]``.
    """
    x = ca.SX.sym("x", 7)
    u = ca.SX.sym("u", 2)
    th, v, beta, r, delta = x[2], x[3], x[4], x[5], x[6]
    v_cmd, delta_cmd = u[0], u[1]
    m, iz = params.mass, params.yaw_inertia
    lf, lr, length = params.lf, params.lr, params.wheelbase
    acc = (v_cmd - v) / params.drive.time_constant
    ddelta = (delta_cmd - delta) / params.steering.time_constant
    # Smooth maximum of v and min_speed: a kink (fmax) stalls the NLP solver when the speed crosses it.
    soft = 0.2 * min_speed
    v_safe = 0.5 * (v + min_speed + ca.sqrt((v - min_speed) ** 2 + soft**2))
    vx = v_safe * ca.cos(beta)
    vy = v_safe * ca.sin(beta)
    alpha_f = delta - ca.atan((vy + lf * r) / vx)
    alpha_r = -ca.atan((vy - lr * r) / vx)
    shift = m * params.h_cg / length * acc
    fz_f = m * params.gravity * lr / length - shift
    fz_r = m * params.gravity * lf / length + shift
    front, rear = (
        tyres if tyres is not None else (PacejkaTyre(params.tyre_front), PacejkaTyre(params.tyre_rear))
    )
    fy_f = tyre_force(front, alpha_f, params.mu * fz_f)
    fy_r = tyre_force(rear, alpha_r, params.mu * fz_r)
    heading = th + beta
    rhs = ca.vertcat(
        v * ca.cos(heading),
        v * ca.sin(heading),
        r,
        acc,
        (fy_f * ca.cos(delta - beta) + fy_r * ca.cos(beta)) / (m * v_safe) - r,
        (lf * fy_f * ca.cos(delta) - lr * fy_r) / iz,
        ddelta,
    )
    return ca.Function("dynamic_ode", [x, u], [rhs], ["x", "u"], ["xdot"])


def rk4_map(ode: Any, dt: float, substeps: int = 1) -> Any:
    """Discrete map of ``dt`` seconds: ``substeps`` classic RK4 steps with the input held.

    Parameters
    ----------
    ode : casadi.Function
        ``f(x, u) -> xdot``.
    dt : float
        Control period (s).
    substeps : int
        RK4 steps per period.

    Returns
    -------
    casadi.Function
        ``F(x, u) -> x_next`` (SX).
    """
    nx = ode.size1_in(0)
    nu = ode.size1_in(1)
    x0 = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", nu)
    h = dt / substeps
    x = x0
    for _ in range(substeps):
        k1 = ode(x, u)
        k2 = ode(x + 0.5 * h * k1, u)
        k3 = ode(x + 0.5 * h * k2, u)
        k4 = ode(x + h * k3, u)
        x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return ca.Function("rk4", [x0, u], [x], ["x", "u"], ["x_next"])
