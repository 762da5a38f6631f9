"""Dynamic single-track plant of a 1:10 car (stand-in for CarSim / the real F1TENTH car).

State ``[x, y, yaw, v, beta, yaw_rate, delta]``: position of the centre of
gravity (m), heading (rad), speed magnitude at the centre of gravity (m/s),
side-slip angle (rad), yaw rate (rad/s) and actual front wheel angle (rad).

Equations (``L = lf + lr``, ``w`` the blending weight below):

* kinematics: ``xdot = v cos(yaw + beta)``, ``ydot = v sin(yaw + beta)``;
* speed loop: ``vdot = a = clip((v_cmd - v) / tau_v, -max_brake, max_accel)``,
  the speed never becomes negative; ``a`` is the tangential acceleration;
* steering servo: ``deltadot = clip((delta_cmd - delta) / tau_s, -max_rate, max_rate)``
  with ``delta_cmd`` clipped to ``+-max_angle``;
* dynamic part: slip angles
  ``alpha_f = delta - atan((v sin(beta) + lf r) / (v cos(beta)))``,
  ``alpha_r = -atan((v sin(beta) - lr r) / (v cos(beta)))``, loads
  ``Fz_f = m (g lr - a h_cg) / L``, ``Fz_r = m (g lf + a h_cg) / L``, Pacejka
  lateral forces (:func:`rkmpc.vehicle.tyres.pacejka_lateral_force`) and

  ``betadot = (Fy_f cos(delta - beta) + Fy_r cos(beta)) / (m v) - r``,
  ``rdot = (lf Fy_f cos(delta) - lr Fy_r) / Iz``, ``yawdot = r``;
* kinematic part: ``beta_k = atan(lr tan(delta) / L)``,
  ``r_k = v cos(beta_k) tan(delta) / L``, ``yawdot = r_k``, with ``beta`` and
  ``r`` following the time derivatives of ``beta_k`` and ``r_k`` plus a fast
  relaxation (time constant 20 ms) towards them, so the state is consistent
  when the car slows down from the dynamic regime;
* ``w = clip((v - blend_speed_low) / (blend_speed_high - blend_speed_low), 0, 1)``
  blends the yaw, side-slip and yaw-rate derivatives linearly, like the
  blended models of CommonRoad and ForzaETH.

Integration is classic RK4 with ``internal_dt`` substeps in plain scalar
Python (``math``), independent of the control period.
"""

from __future__ import annotations

from collections.abc import Callable

from rkmpc.vehicle.actuators import limit_accel
from rkmpc.vehicle.chassis import build_chassis
from rkmpc.vehicle.friction import FrictionSchedule
from rkmpc.vehicle.params import VehicleParams, f1tenth
from rkmpc.vehicle.plants.base import SingleTrackPlant
from rkmpc.vehicle.tyres import PacejkaTyre

__all__ = ["DynamicPlant"]

_Derivative = tuple[float, float, float, float, float, float, float]
_Rhs = Callable[[float, float, float, float, float, float, float, float], _Derivative]


def _build_rhs(p: VehicleParams) -> _Rhs:
    """Return the right-hand side ``f(yaw, v, beta, r, delta, v_cmd, delta_cmd, mu)``.

    The servo lag and the speed loop act inside the derivative (so RK4
    integrates them with the chassis); :func:`rkmpc.vehicle.chassis.build_chassis`
    gives the rest. ``v_cmd`` and ``delta_cmd`` must already be clipped to the
    actuator limits.
    """
    chassis = build_chassis(p, PacejkaTyre(p.tyre_front).build(), PacejkaTyre(p.tyre_rear).build())
    tau_v = p.drive.time_constant
    max_accel, max_brake = p.drive.max_accel, p.drive.max_brake
    tau_s = p.steering.time_constant
    max_rate = p.steering.max_rate

    def rhs(
        yaw: float, v: float, beta: float, r: float, delta: float, v_cmd: float, delta_cmd: float, mu: float
    ) -> _Derivative:
        acc = limit_accel((v_cmd - v) / tau_v, v, max_accel, max_brake)
        ddelta = (delta_cmd - delta) / tau_s
        if ddelta > max_rate:
            ddelta = max_rate
        elif ddelta < -max_rate:
            ddelta = -max_rate
        dx, dy, dyaw, dbeta, dr = chassis(yaw, v, beta, r, delta, ddelta, acc, mu)
        return dx, dy, dyaw, acc, dbeta, dr, ddelta

    return rhs


def _stage(
    rhs: _Rhs,
    c: float,
    k: _Derivative,
    yaw: float,
    v: float,
    beta: float,
    r: float,
    delta: float,
    v_cmd: float,
    d_cmd: float,
    mu: float,
) -> _Derivative:
    """An RK4 stage: ``rhs`` at the state moved ``c`` (s) along the derivative ``k``."""
    return rhs(
        yaw + c * k[2], v + c * k[3], beta + c * k[4], r + c * k[5], delta + c * k[6], v_cmd, d_cmd, mu
    )


class DynamicPlant(SingleTrackPlant):
    """Blended kinematic/dynamic single-track car with Pacejka tyres and actuators.

    See the module docstring for the equations.

    Parameters
    ----------
    params : VehicleParams or None, optional
        Car parameters; :func:`rkmpc.vehicle.params.f1tenth` when None.
    internal_dt : float, optional
        RK4 substep (s); each call of :meth:`step` uses ``ceil(dt / internal_dt)``
        substeps, the last one shorter when ``dt`` is not a multiple.
    input_delay : float, optional
        Delay (s) between :meth:`step` receiving a command and the actuators
        seeing it; 0 for none.
    friction : FrictionSchedule or None, optional
        Multiplier of ``params.mu`` as a function of time and position,
        evaluated at the start of every substep; None for constant friction.
    """

    def __init__(
        self,
        params: VehicleParams | None = None,
        *,
        internal_dt: float = 1e-3,
        input_delay: float = 0.0,
        friction: FrictionSchedule | None = None,
    ) -> None:
        vehicle = f1tenth() if params is None else params
        self._rhs = _build_rhs(vehicle)
        self._s: list[float] = [0.0] * 7
        super().__init__(vehicle, internal_dt=internal_dt, input_delay=input_delay, friction=friction)

    def _advance(self, duration: float, setpoint: tuple[float, float]) -> None:
        if duration <= 0.0:
            return
        v_cmd, d_cmd = self._clamped_setpoint(setpoint)
        mu0 = self.params.mu
        rhs = self._rhs
        x, y, yaw, v, beta, r, delta = self._s
        t = self._time
        for h in self._substeps(duration):
            mu = mu0 if self.friction is None else mu0 * self.friction(t, x, y)
            hh = 0.5 * h
            k1 = rhs(yaw, v, beta, r, delta, v_cmd, d_cmd, mu)
            k2 = _stage(rhs, hh, k1, yaw, v, beta, r, delta, v_cmd, d_cmd, mu)
            k3 = _stage(rhs, hh, k2, yaw, v, beta, r, delta, v_cmd, d_cmd, mu)
            k4 = _stage(rhs, h, k3, yaw, v, beta, r, delta, v_cmd, d_cmd, mu)
            h6 = h / 6.0
            x += h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
            y += h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
            yaw += h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2])
            v += h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3])
            beta += h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4])
            r += h6 * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])
            delta += h6 * (k1[6] + 2.0 * (k2[6] + k3[6]) + k4[6])
            if v < 0.0:
                v = 0.0
            t += h
        self._s = [x, y, yaw, v, beta, r, delta]
