"""The blended kinematic/dynamic single-track chassis shared by the simulated 1:10 cars.

:func:`build_chassis` returns the time derivatives of the chassis state
``[x, y, yaw, beta, yaw_rate]`` for a given speed ``v``, tangential
acceleration ``a``, front wheel angle ``delta`` and its rate, and friction
``mu``; the actuators that produce ``a`` and ``delta`` belong to the plant.
The equations are documented in :mod:`rkmpc.vehicle.plants.dynamic`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.tyres import LateralForce

__all__ = ["KINEMATIC_RELAXATION_TIME", "Chassis", "build_chassis"]

#: Time constant (s) with which side-slip and yaw rate relax to their kinematic values.
KINEMATIC_RELAXATION_TIME = 0.02

#: ``chassis(yaw, v, beta, r, delta, ddelta, acc, mu) -> (dx, dy, dyaw, dbeta, dr)``.
Chassis = Callable[
    [float, float, float, float, float, float, float, float], tuple[float, float, float, float, float]
]


def build_chassis(p: VehicleParams, front: LateralForce, rear: LateralForce) -> Chassis:
    """The chassis derivatives of the car ``p`` with the axle force laws ``front`` and ``rear``.

    The constants are bound as closure variables so the inner loop touches
    no attributes.

    Parameters
    ----------
    p : VehicleParams
        Mass, inertia, geometry and blending speeds (the tyre and actuator
        fields are not used here).
    front, rear : LateralForce
        ``force(alpha, fz, mu)`` (N) of each axle.

    Returns
    -------
    Chassis
        ``(yaw, v, beta, r, delta, ddelta, acc, mu) -> (dx, dy, dyaw, dbeta, dr)``
        in rad, m/s, rad, rad/s, rad, rad/s, m/s^2 and - .
    """
    sin, cos, tan, atan = math.sin, math.cos, math.tan, math.atan
    mass = p.mass
    inertia = p.yaw_inertia
    lf, lr = p.lf, p.lr
    length = p.wheelbase
    lr_frac = lr / length
    fz_f_static = mass * p.gravity * lr / length
    fz_r_static = mass * p.gravity * lf / length
    load_shift = mass * p.h_cg / length
    v_low = p.blend_speed_low
    inv_blend = 1.0 / (p.blend_speed_high - p.blend_speed_low)
    inv_relax = 1.0 / KINEMATIC_RELAXATION_TIME
    v_floor = 1e-3

    def chassis(
        yaw: float, v: float, beta: float, r: float, delta: float, ddelta: float, acc: float, mu: float
    ) -> tuple[float, float, float, float, float]:
        heading = yaw + beta
        dx = v * cos(heading)
        dy = v * sin(heading)

        w = (v - v_low) * inv_blend
        if w < 0.0:
            w = 0.0
        elif w > 1.0:
            w = 1.0

        dyaw = dbeta = dr = 0.0
        if w < 1.0:
            tan_d = tan(delta)
            cos_d = cos(delta)
            sec2 = 1.0 / (cos_d * cos_d)
            q = lr_frac * tan_d
            beta_k = atan(q)
            cos_bk = cos(beta_k)
            dbeta_k = lr_frac * sec2 * ddelta / (1.0 + q * q)
            r_k = v * cos_bk * tan_d / length
            dr_k = (
                acc * cos_bk * tan_d - v * sin(beta_k) * dbeta_k * tan_d + v * cos_bk * sec2 * ddelta
            ) / length
            wk = 1.0 - w
            dyaw = wk * r_k
            dbeta = wk * (dbeta_k + (beta_k - beta) * inv_relax)
            dr = wk * (dr_k + (r_k - r) * inv_relax)
        if w > 0.0:
            cos_b = cos(beta)
            vx = v * cos_b
            if vx < v_floor:
                vx = v_floor
            vy = v * sin(beta)
            alpha_f = delta - atan((vy + lf * r) / vx)
            alpha_r = -atan((vy - lr * r) / vx)
            shift = load_shift * acc
            fy_f = front(alpha_f, fz_f_static - shift, mu)
            fy_r = rear(alpha_r, fz_r_static + shift, mu)
            dyaw += w * r
            dbeta += w * ((fy_f * cos(delta - beta) + fy_r * cos_b) / (mass * v) - r)
            dr += w * (lf * fy_f * cos(delta) - lr * fy_r) / inertia
        return dx, dy, dyaw, dbeta, dr

    return chassis
