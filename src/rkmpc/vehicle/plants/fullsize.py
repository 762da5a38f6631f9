"""Full-size car plant (the paper's CarSim setting): CommonRoad's drift model of a BMW 320i.

The vehicle dynamics are ``vehiclemodels.vehicle_dynamics_std`` (single-track
drift model with Pacejka combined-slip tyres, wheel spin dynamics and blending
to a kinematic model below about 0.3 m/s) with the parameters of
``vehiclemodels.parameters_vehicle2`` (BMW 320i), from
commonroad-vehicle-models 3.0.2. The controllers' set-points reach it through
the same actuators as :class:`rkmpc.vehicle.plants.dynamic.DynamicPlant`:

* steering servo, fed to the model as its steering-velocity input:
  ``deltadot = clip((delta_cmd - delta) / tau_s, -max_rate, max_rate)``;
* speed loop, fed as its longitudinal-acceleration input:
  ``a = clip((v_cmd - v) / tau_v, -max_brake, max_accel)``;

after which the package applies its own steering and acceleration
constraints. The wheel spin dynamics are stiff (time constants below a
millisecond at walking speed), so the model is integrated with SciPy's LSODA,
which switches to an implicit method when needed, with ``internal_dt`` as the
largest step.

When the car spins (side slip beyond +-90 degrees, sliding backwards along its
heading) the model's wheel speeds sit at its clamp ``omega >= 0`` while the
wheels' forward speed is cut to 0, so the longitudinal slip divides by the
model's floor of 0.1 m/s: the wheel equations become about a hundred times
stiffer than in normal driving (time constants near 20 microseconds) and
switch at the clamp. LSODA then fails with repeated convergence failures
("Unexpected istate in LSODA"; seen on Catalunya under the LMPC) or crawls
with ever smaller steps. A step LSODA cannot integrate within
:data:`MAX_EVALUATIONS` evaluations is integrated again from the same state with the implicit BDF
method, then Radau (:data:`INTEGRATORS`); only when all of them fail does the
plant raise :class:`~rkmpc.core.errors.PlantIntegrationError`, which the closed
loop records as the outcome ``"plant_failure"``.

State (the package's order): ``[x, y, delta, v, yaw, yaw_rate, beta, omega_f,
omega_r]`` -- position (m), front wheel angle (rad), speed at the centre of
gravity (m/s), heading (rad), yaw rate (rad/s), side-slip angle (rad), front
and rear wheel angular speeds (rad/s).
"""

from __future__ import annotations

import copy
import math
import warnings
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.vehicle_dynamics_std import vehicle_dynamics_std

from rkmpc.core.errors import ParameterError, PlantIntegrationError
from rkmpc.core.observation import Observation
from rkmpc.vehicle.friction import FrictionSchedule
from rkmpc.vehicle.params import VehicleParams, fullsize
from rkmpc.vehicle.plants.base import ActuatedPlant, single_track_observation

__all__ = ["INTEGRATORS", "MAX_EVALUATIONS", "FullSizePlant", "fullsize"]

_RTOL = 1e-6
_ATOL = 1e-6

#: SciPy methods tried in turn on each step: LSODA, then implicit fall-backs for a step it cannot do.
INTEGRATORS = ("LSODA", "BDF", "Radau")
#: Evaluations of the dynamics one method may spend on one integration interval before it gives up.
MAX_EVALUATIONS = 5000


class _TooManyEvaluations(Exception):
    """An integration attempt used up :data:`MAX_EVALUATIONS`."""


class FullSizePlant(ActuatedPlant):
    """CommonRoad single-track drift model of a BMW 320i behind a servo and a speed loop.

    Parameters
    ----------
    internal_dt : float, optional
        Largest integration step of the LSODA solver (s).
    input_delay : float, optional
        Delay (s) between :meth:`step` receiving a command and the actuators
        seeing it; 0 for none.
    friction : FrictionSchedule or None, optional
        Friction multiplier as a function of time and position. It scales the
        package's tyre peak factors ``p_dx1`` and ``p_dy1`` (the magic
        formula keeps the cornering stiffness and lowers the force peak);
        None for the nominal road.
    params : VehicleParams or None, optional
        Actuator limits and the wheelbase reported to controllers;
        :func:`rkmpc.vehicle.params.fullsize` when None. Chassis and tyre
        values always come from the package (scaled by the two options below).
    mass_scale : float, optional
        Multiplier (-) of the package's mass ``m`` and yaw inertia ``I_z``
        (a loaded car with the same radius of gyration and centre of gravity,
        so each axle's load grows alike). ``params`` is reported as given.
    grip_scale : float, optional
        Multiplier (-) of the tyres' force per unit load: the peak factors
        ``p_dx1``, ``p_dy1`` and the slip stiffness factors ``p_kx1``,
        ``p_ky1``. The friction schedule acts on top of it.

    Attributes
    ----------
    STATE_NAMES : tuple of str
        ``("x", "y", "delta", "v", "yaw", "yaw_rate", "beta", "omega_f", "omega_r")``.
    fallback_steps : int
        Integration intervals since the last reset that LSODA could not do and a fall-back
        method of :data:`INTEGRATORS` did.
    """

    STATE_NAMES: tuple[str, ...] = ("x", "y", "delta", "v", "yaw", "yaw_rate", "beta", "omega_f", "omega_r")

    def __init__(
        self,
        *,
        internal_dt: float = 1e-3,
        input_delay: float = 0.0,
        friction: FrictionSchedule | None = None,
        params: VehicleParams | None = None,
        mass_scale: float = 1.0,
        grip_scale: float = 1.0,
    ) -> None:
        for name, value in (("mass_scale", mass_scale), ("grip_scale", grip_scale)):
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"FullSizePlant.{name} must be finite and > 0, got {value!r}")
        self.mass_scale = float(mass_scale)
        self.grip_scale = float(grip_scale)
        self._model: Any = copy.deepcopy(parameters_vehicle2())
        if self.mass_scale != 1.0:
            self._model.m = float(self._model.m) * self.mass_scale
            self._model.I_z = float(self._model.I_z) * self.mass_scale
        if self.grip_scale != 1.0:
            tire = self._model.tire
            for key in ("p_dx1", "p_dy1", "p_kx1", "p_ky1"):
                setattr(tire, key, float(getattr(tire, key)) * self.grip_scale)
        self._nominal_dx1 = float(self._model.tire.p_dx1)
        self._nominal_dy1 = float(self._model.tire.p_dy1)
        self._applied_factor = 1.0
        self._s = np.zeros(len(self.STATE_NAMES))
        self.fallback_steps = 0
        vehicle = fullsize() if params is None else params
        super().__init__(vehicle, internal_dt=internal_dt, input_delay=input_delay, friction=friction)

    def _reset_state(self, x: float, y: float, yaw: float, speed: float, steer: float) -> None:
        length = self.params.wheelbase
        beta = math.atan(self.params.lr / length * math.tan(steer))
        yaw_rate = speed * math.cos(beta) * math.tan(steer) / length
        radius = float(self._model.R_w)
        omega_f = speed * math.cos(beta) * math.cos(steer) / radius
        omega_r = speed * math.cos(beta) / radius
        self._s = np.array([x, y, steer, speed, yaw, yaw_rate, beta, omega_f, omega_r])
        self.fallback_steps = 0
        self._set_friction(1.0)

    def _set_friction(self, factor: float) -> None:
        if factor != self._applied_factor:
            self._model.tire.p_dx1 = self._nominal_dx1 * factor
            self._model.tire.p_dy1 = self._nominal_dy1 * factor
            self._applied_factor = factor

    def _rhs(self, t: float, s: np.ndarray, v_cmd: float, d_cmd: float) -> list[float]:
        state = s.tolist()
        self._set_friction(self.friction_factor(t, state[0], state[1]))
        steering = self.params.steering
        drive = self.params.drive
        rate = (d_cmd - state[2]) / steering.time_constant
        rate = min(max(rate, -steering.max_rate), steering.max_rate)
        speed = state[3]
        acc = (v_cmd - speed) / drive.time_constant
        acc = min(max(acc, -drive.max_brake), drive.max_accel)
        if speed <= 0.0 and acc < 0.0:
            acc = 0.0
        derivative: list[float] = vehicle_dynamics_std(state, [rate, acc], self._model)
        return derivative

    def _advance(self, duration: float, setpoint: tuple[float, float]) -> None:
        if duration <= 0.0:
            return
        v_cmd, d_cmd = self._clamped_setpoint(setpoint)
        start = self._time
        failures: list[str] = []
        for method in INTEGRATORS:
            end_state, problem = self._integrate(method, start, duration, v_cmd, d_cmd)
            if end_state is not None:
                break
            failures.append(f"{method}: {problem}")
        else:
            state_text = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.STATE_NAMES, self._s, strict=True))
            raise PlantIntegrationError(
                f"full-size plant integration failed at t={start:.3f} s ({'; '.join(failures)}); "
                f"state {state_text}",
                start,
            )
        self.fallback_steps += int(bool(failures))
        state = end_state
        state[3] = max(state[3], 0.0)
        state[7] = max(state[7], 0.0)
        state[8] = max(state[8], 0.0)
        self._s = state

    def _integrate(
        self, method: str, start: float, duration: float, v_cmd: float, d_cmd: float
    ) -> tuple[np.ndarray | None, str]:
        """The state after ``duration`` s by one SciPy method, or None and why it failed.

        An attempt that needs more than :data:`MAX_EVALUATIONS` evaluations of the dynamics
        gives up (LSODA can crawl instead of failing on a spinning car); one whose method raises
        on a non-finite or out-of-domain value fails with that message.
        """
        count = 0

        def rhs(t: float, s: np.ndarray) -> list[float]:
            nonlocal count
            count += 1
            if count > MAX_EVALUATIONS:
                raise _TooManyEvaluations
            return self._rhs(t, s, v_cmd, d_cmd)

        try:
            with warnings.catch_warnings():
                # LSODA warns before it gives up; its failure is handled by the caller.
                warnings.simplefilter("ignore", UserWarning)
                solution = solve_ivp(
                    rhs,
                    (start, start + duration),
                    self._s,
                    method=method,
                    rtol=_RTOL,
                    atol=_ATOL,
                    max_step=self.internal_dt,
                    first_step=min(self.internal_dt, duration),
                )
        except _TooManyEvaluations:
            return None, f"more than {MAX_EVALUATIONS} evaluations"
        except (ValueError, ArithmeticError) as exc:  # a method choking on a non-finite state
            return None, f"{type(exc).__name__}: {exc}"
        end = solution.y[:, -1]
        if not solution.success or not np.isfinite(end).all():
            return None, str(solution.message) if not solution.success else "non-finite state"
        return end.copy(), ""

    def observe(self) -> Observation:
        """True observation; ``speed`` is the velocity along the heading, ``v cos(beta)``."""
        x, y, delta, v, yaw, yaw_rate, beta = (float(value) for value in self._s[:7])
        return single_track_observation(x, y, yaw, v, beta, yaw_rate, delta, self._time)

    @property
    def state(self) -> np.ndarray:
        return self._s.copy()

    @property
    def wheel_angle(self) -> float:
        return float(self._s[2])
