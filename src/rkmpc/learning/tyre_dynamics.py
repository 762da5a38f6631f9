"""The lateral dynamics of the single-track model on arrays: what tyre identification predicts with.

Over a control period the side slip ``beta`` and the yaw rate ``r`` of the chassis follow the
dynamic regime of :mod:`rkmpc.vehicle.plants.dynamic`:

* ``beta' = (Fy_f cos(delta - beta) + Fy_r cos(beta)) / (m v) - r``,
* ``r' = (lf Fy_f cos(delta) - lr Fy_r) / Iz``,

with the slip angles ``alpha_f = delta - atan((v sin beta + lf r) / (v cos beta))`` and
``alpha_r = -atan((v sin beta - lr r) / (v cos beta))``, the axle forces ``Fy = Fz f(alpha)``
(``f`` a curve per unit load, :class:`~rkmpc.learning.tyre_model.AxleCurve`) and the loads
``Fz_f = m (g lr - a h) / L``, ``Fz_r = m (g lf + a h) / L``. The speed ``v`` (m/s, the speed
magnitude) and the wheel angle ``delta`` (rad) are given at both ends of every period and taken
linear in between, the tangential acceleration ``a`` as their slope; :func:`predict` integrates
with :data:`SUBSTEPS` RK4 steps per period, vectorised over many runs at once.

A :class:`Runs` holds M runs of W consecutive periods each: W = 1 when the side slip is
measured (every transition predicted from its own measured start), longer runs from an estimated
start when it is not (scored after a burn-in that forgets the start).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rkmpc.vehicle.params import VehicleParams

__all__ = ["SUBSTEPS", "Chassis", "Law", "Runs", "predict", "slip_angles"]

#: RK4 steps per control period (the lateral modes of a 1:10 car at 1 m/s decay at about 60/s).
SUBSTEPS = 4

#: Lateral force per unit vertical load (-) of one axle at the slip angles given (rad).
Law = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Chassis:
    """Mass (kg), yaw inertia (kg m^2), axle distances (m), height of the centre of gravity (m), g (m/s^2)."""

    mass: float
    yaw_inertia: float
    lf: float
    lr: float
    h_cg: float
    gravity: float

    @classmethod
    def of(cls, vehicle: VehicleParams) -> Chassis:
        """The chassis of ``vehicle`` (its tyres are what is identified)."""
        return cls(vehicle.mass, vehicle.yaw_inertia, vehicle.lf, vehicle.lr, vehicle.h_cg, vehicle.gravity)

    def loads(self, acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vertical loads (N) of the front and rear axle at the tangential ``acceleration`` (m/s^2)."""
        length = self.lf + self.lr
        shift = self.mass * self.h_cg / length * acceleration
        return (
            self.mass * self.gravity * self.lr / length - shift,
            self.mass * self.gravity * self.lf / length + shift,
        )


@dataclass(frozen=True)
class Runs:
    """M runs of W consecutive control periods; arrays (M, W + 1) at the period boundaries.

    Parameters
    ----------
    speed, wheel : numpy.ndarray
        Speed magnitude (m/s) and front wheel angle (rad).
    beta0, yaw_rate0 : numpy.ndarray
        Side slip (rad) and yaw rate (rad/s) each run starts from, shape (M,).
    yaw_rate, lateral : numpy.ndarray
        Measured yaw rate (rad/s) and lateral velocity ``v sin(beta)`` (m/s; NaN when not measured).
    scored : numpy.ndarray
        Which boundaries are predicted and scored (bool; never the first).
    dt : float
        Control period (s).
    """

    speed: np.ndarray
    wheel: np.ndarray
    beta0: np.ndarray
    yaw_rate0: np.ndarray
    yaw_rate: np.ndarray
    lateral: np.ndarray
    scored: np.ndarray
    dt: float

    def subset(self, rows: np.ndarray) -> Runs:
        """The runs ``rows`` (bool or index array)."""
        return Runs(
            self.speed[rows],
            self.wheel[rows],
            self.beta0[rows],
            self.yaw_rate0[rows],
            self.yaw_rate[rows],
            self.lateral[rows],
            self.scored[rows],
            self.dt,
        )


def slip_angles(
    chassis: Chassis, speed: np.ndarray, beta: np.ndarray, yaw_rate: np.ndarray, wheel: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Front and rear slip angles (rad) of the single-track model."""
    vx = speed * np.cos(beta)
    vy = speed * np.sin(beta)
    front = wheel - np.arctan((vy + chassis.lf * yaw_rate) / vx)
    rear = -np.arctan((vy - chassis.lr * yaw_rate) / vx)
    return front, rear


def _rates(
    chassis: Chassis,
    laws: tuple[Law, Law],
    inputs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    beta: np.ndarray,
    yaw_rate: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``(beta', r')`` at the speed, wheel angle and axle loads ``inputs``."""
    v, delta, fz_f, fz_r = inputs
    alpha_f, alpha_r = slip_angles(chassis, v, beta, yaw_rate, delta)
    fy_f = fz_f * laws[0](alpha_f)
    fy_r = fz_r * laws[1](alpha_r)
    dbeta = (fy_f * np.cos(delta - beta) + fy_r * np.cos(beta)) / (chassis.mass * v) - yaw_rate
    return dbeta, (chassis.lf * fy_f * np.cos(delta) - chassis.lr * fy_r) / chassis.yaw_inertia


def _inputs(
    period: tuple[np.ndarray, ...], s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Speed, wheel angle and loads at the fraction ``s`` of a period ``(v0, dv, d0, dd, fz_f, fz_r)``."""
    v0, dv, d0, dd, fz_f, fz_r = period
    return v0 + dv * s, d0 + dd * s, fz_f, fz_r


def predict(runs: Runs, chassis: Chassis, front: Law, rear: Law) -> tuple[np.ndarray, np.ndarray]:
    """Side slip (rad) and yaw rate (rad/s) at every boundary of every run, shapes (M, W + 1).

    Each run starts from its ``beta0`` and ``yaw_rate0`` and is integrated through its periods
    with :data:`SUBSTEPS` RK4 steps each, ``front`` and ``rear`` giving the axle forces per unit load.
    """
    laws = (front, rear)
    beta = np.empty_like(runs.speed)
    r = np.empty_like(runs.speed)
    beta[:, 0], r[:, 0] = runs.beta0, runs.yaw_rate0
    h = runs.dt / SUBSTEPS
    for j in range(runs.speed.shape[1] - 1):
        v0, dv = runs.speed[:, j], runs.speed[:, j + 1] - runs.speed[:, j]
        d0, dd = runs.wheel[:, j], runs.wheel[:, j + 1] - runs.wheel[:, j]
        period = (v0, dv, d0, dd, *chassis.loads(dv / runs.dt))
        b, yr = beta[:, j], r[:, j]
        for k in range(SUBSTEPS):
            start, mid, end = (_inputs(period, (k + f) / SUBSTEPS) for f in (0.0, 0.5, 1.0))
            k1 = _rates(chassis, laws, start, b, yr)
            k2 = _rates(chassis, laws, mid, b + 0.5 * h * k1[0], yr + 0.5 * h * k1[1])
            k3 = _rates(chassis, laws, mid, b + 0.5 * h * k2[0], yr + 0.5 * h * k2[1])
            k4 = _rates(chassis, laws, end, b + h * k3[0], yr + h * k3[1])
            b = b + h / 6.0 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0])
            yr = yr + h / 6.0 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1])
        beta[:, j + 1], r[:, j + 1] = b, yr
    return beta, r
