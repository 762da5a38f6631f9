"""The estimator's process and measurement models: a single-track car with sensor scale and bias.

State (:data:`STATE_NAMES`), SI units: position of the centre of gravity ``x, y`` (m), heading
``yaw`` (rad, continuous), body-frame velocities ``vx, vy`` (m/s), yaw rate ``r`` (rad/s), the
wheel-speed sensor's scale ``k`` (-) and the gyro's bias ``b`` (rad/s).

Process over a step ``h`` (s) with the front wheel angle ``delta`` (rad) from the steering model:

* kinematics at the mid-step heading ``psi_m = yaw + r h / 2``:
  ``x += h (vx cos psi_m - vy sin psi_m)``, ``y += h (vx sin psi_m + vy cos psi_m)``, ``yaw += h r``;
* ``vx``, ``k``, ``b``: random walks (the measurements carry them);
* ``r`` relaxes (time constant ``tau_r``) to the steady cornering rate of the wheel angle,
  ``r_ss = vx tan(delta) / (L + K vx^2)`` (``K`` the understeer gradient);
* ``vy`` relaxes (``tau_y``) to the steady lateral velocity of the rear axle at that yaw rate,
  ``vy_ss = r (lr - m lf vx^2 / (L C_r))``: the rear tyres' slip carries the share ``lf / L`` of
  the centripetal force, ``C_r`` their cornering stiffness (linear tyre; kinematic, ``lr r``, at
  rest). This is where the slip angle's estimate comes from (see the filter's notes).

Measurements: the pose ``[x, y, yaw]`` measured ``lag`` seconds ago, predicted from the state by
going back along the current velocities (``x - lag (vx cos psi_b - vy sin psi_b)``, ... with
``psi_b = yaw - r lag / 2``, ``yaw - r lag``); the wheel speed ``k vx``; the gyro ``r + b``; a
slip angle ``atan2(vy, vx)``.
"""

from __future__ import annotations

import math

import numpy as np

from rkmpc.estimation.config import EstimatorConfig
from rkmpc.vehicle.params import VehicleParams

__all__ = ["N_STATES", "STATE_NAMES", "SingleTrackModel", "axle_cornering_stiffness", "slip_of"]

#: The estimator's state, in order.
STATE_NAMES: tuple[str, ...] = ("x", "y", "yaw", "vx", "vy", "yaw_rate", "speed_scale", "gyro_bias")
N_STATES = len(STATE_NAMES)
X, Y, YAW, VX, VY, R, SCALE, BIAS = range(N_STATES)
#: Speed (m/s) below which the slip angle's denominator is held.
_SLIP_SPEED_FLOOR = 0.1


def slip_of(vx: float, vy: float) -> float:
    """Side-slip angle (rad) of body velocities ``vx, vy`` (m/s): ``atan(vy / max(|vx|, 0.1))``.

    The angle of the velocity from the car's axis, on the side of the direction of travel (so
    also for a car reversing); held finite near standstill.
    """
    return math.atan(vy / max(abs(vx), _SLIP_SPEED_FLOOR))


def axle_cornering_stiffness(vehicle: VehicleParams) -> tuple[float, float]:
    """Static cornering stiffness of the front and rear axle (N/rad): ``B C D mu Fz`` at rest."""
    m, g, length = vehicle.mass, vehicle.gravity, vehicle.wheelbase
    fz_f = m * g * vehicle.lr / length
    fz_r = m * g * vehicle.lf / length
    mu = vehicle.mu
    return (
        vehicle.tyre_front.cornering_stiffness_per_load * mu * fz_f,
        vehicle.tyre_rear.cornering_stiffness_per_load * mu * fz_r,
    )


class SingleTrackModel:
    """The transition, its Jacobian and the measurement functions of the module docstring.

    Parameters
    ----------
    vehicle : VehicleParams
        Mass, geometry and tyres (cornering stiffness).
    config : EstimatorConfig
        Relaxation times, the understeer gradient (or None for the tyres' own) and noise densities.
    """

    def __init__(self, vehicle: VehicleParams, config: EstimatorConfig) -> None:
        c_f, c_r = axle_cornering_stiffness(vehicle)
        length = vehicle.wheelbase
        self.length = length
        self.lr = vehicle.lr
        if config.understeer_gradient is None:
            self.understeer = vehicle.mass / length * (vehicle.lr / c_f - vehicle.lf / c_r)
        else:
            self.understeer = float(config.understeer_gradient)
        #: ``m lf / (L C_r)`` (s^2/m): how the rear axle's slip grows with the lateral acceleration.
        self.rear_compliance = vehicle.mass * vehicle.lf / (length * c_r)
        self.tau_r = config.yaw_rate_time_constant
        self.tau_y = config.lateral_time_constant
        #: Process noise per second: ``Q = diag(q) h`` over a step of ``h`` seconds.
        self.q = np.array([d * d for d in config.process_densities()])
        self._q_matrix = np.diag(self.q)
        self._q_step, self._q_last = 0.0, self._q_matrix * 0.0
        self.F = np.eye(N_STATES)
        self._pose_now = np.eye(3, N_STATES)
        self._pose_lagged = np.eye(3, N_STATES)

    def effective_wheelbase(self, vx: float) -> float:
        """``L + K vx^2`` (m), kept at least ``L / 10`` (an oversteering car past its critical speed)."""
        return max(self.length + self.understeer * vx * vx, 0.1 * self.length)

    def steady_yaw_rate(self, vx: float, delta: float) -> float:
        """Yaw rate (rad/s) of steady cornering at speed ``vx`` (m/s) and wheel angle ``delta`` (rad)."""
        return vx * math.tan(delta) / self.effective_wheelbase(vx)

    def lateral_gain(self, vx: float) -> float:
        """``vy_ss / r`` (m) at speed ``vx`` (m/s): ``lr - m lf vx^2 / (L C_r)``."""
        return self.lr - self.rear_compliance * vx * vx

    def process_noise(self, h: float) -> np.ndarray:
        """``Q`` (8, 8) of a step of ``h`` seconds (the last one kept: steps repeat).

        ``diag(q) h``, except that the yaw acceleration's white noise (density ``q_r``) moves the
        heading too, by its integral over the step: ``Q[yaw, yaw] += q_r h^3 / 3`` and
        ``Q[yaw, r] = q_r h^2 / 2``. Without the coupling the yaw rate a gyro measures at the end
        of a step corrects the rate, not the heading the rate turned through, and the heading lags
        the truth by a fraction of the step wherever the rate changes.
        """
        if h != self._q_step:
            q = self._q_matrix * h
            q_r = self.q[R]
            q[YAW, YAW] += q_r * h**3 / 3.0
            q[YAW, R] = q[R, YAW] = q_r * h * h / 2.0
            self._q_step, self._q_last = h, q
        return self._q_last

    def transition(self, state: list[float], h: float, delta: float) -> list[float]:
        """The state ``h`` seconds on (a new list); fills :attr:`F`, its Jacobian."""
        x, y, yaw, vx, vy, r, k, b = state
        psi = yaw + 0.5 * h * r
        c, s = math.cos(psi), math.sin(psi)
        along = vx * c - vy * s  # velocity in the world frame
        across = vx * s + vy * c
        a_r = math.exp(-h / self.tau_r)
        a_y = math.exp(-h / self.tau_y)
        tan_d = math.tan(delta)
        l_eff = self.effective_wheelbase(vx)
        r_ss = vx * tan_d / l_eff
        gain = self.lateral_gain(vx)
        F = self.F
        F[X, YAW] = -h * across
        F[X, VX] = h * c
        F[X, VY] = -h * s
        F[X, R] = -0.5 * h * h * across
        F[Y, YAW] = h * along
        F[Y, VX] = h * s
        F[Y, VY] = h * c
        F[Y, R] = 0.5 * h * h * along
        F[YAW, R] = h
        F[VY, VX] = -(1.0 - a_y) * r * 2.0 * self.rear_compliance * vx
        F[VY, VY] = a_y
        F[VY, R] = (1.0 - a_y) * gain
        # d r_ss / d vx, where L + K vx^2 is not at its floor.
        floor = l_eff <= 0.1 * self.length
        slope = 1.0 / l_eff if floor else (self.length - self.understeer * vx * vx) / (l_eff * l_eff)
        F[R, VX] = (1.0 - a_r) * tan_d * slope
        F[R, R] = a_r
        return [
            x + h * along,
            y + h * across,
            yaw + h * r,
            vx,
            a_y * vy + (1.0 - a_y) * gain * r,
            a_r * r + (1.0 - a_r) * r_ss,
            k,
            b,
        ]

    def pose(self, state: list[float], lag: float) -> tuple[list[float], np.ndarray]:
        """The pose ``[x, y, yaw]`` ``lag`` seconds ago predicted from ``state``, and its Jacobian (3, 8)."""
        x, y, yaw, vx, vy, r, _, _ = state
        if lag <= 0.0:
            return [x, y, yaw], self._pose_now
        H = self._pose_lagged
        psi = yaw - 0.5 * lag * r
        c, s = math.cos(psi), math.sin(psi)
        along = vx * c - vy * s
        across = vx * s + vy * c
        H[0, YAW] = lag * across
        H[0, VX] = -lag * c
        H[0, VY] = lag * s
        H[0, R] = -0.5 * lag * lag * across
        H[1, YAW] = -lag * along
        H[1, VX] = -lag * s
        H[1, VY] = -lag * c
        H[1, R] = 0.5 * lag * lag * along
        H[2, R] = -lag
        return [x - lag * along, y - lag * across, yaw - lag * r], H
