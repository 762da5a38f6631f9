"""``nmpc-id``: the dynamic NMPC on what two laps identify, in real time.

:class:`~rkmpc.control.nonlinear.nmpc.DynamicNMPC` (``nmpc-dynamic``) is given the car's nominal
dynamic model: Pacejka tyres, servo and speed loop from the data sheet. ``nmpc-id`` is the same
NLP on the model identified from laps of the track (:func:`rkmpc.learning.learn.learn` with the
``identified-tyres`` recipe):

* the tyre curves of :mod:`rkmpc.learning.tyre_fit` (linear, Pacejka, or the nominal ones
  scaled; the nominal ones when nothing predicted better, marked so in the model). The
  understeer the kinematic fit identifies is not used: in a dynamic model it follows from the
  tyres (``K = (1 / c_f - 1 / c_r) / g``, reported beside it);
* the servo the tyres were identified with (``model.tyres.servo``: the identified one; or, when
  that was fitted on the yaw rate and so holds the chassis's lag, its lag alone or the car's
  nominal servo, whichever predicted the held-out data best): its lag, with a pure delay folded
  into it (``tau + d``; the NLP's model is a first-order lag), and a rate limit, when one was
  identified, as the steering-step limit; the wheel angle the state starts from is run from the
  commands through that servo, delay included, when it is not measured or when the tyres were
  fitted on a wheel run that way;
* without a side-slip measurement, the side slip the state starts from is the steady-state one
  of the identified rear tyres, ``lr r / v - v r / (g c_r)`` (``nmpc-dynamic`` takes the
  kinematic one).

The chassis (mass, inertia, axle distances) and the speed loop are the car's nominal ones. Built
from a car's settings (:meth:`IdentifiedDynamicNMPC.from_settings`) it runs the real-time path:
one SQP iteration per period (:data:`REAL_TIME`), warm-started from the previous plan. Stiffer
identified tyres make faster lateral modes: unless the config sets them, the RK4 steps per period
are as many as keep those modes (linearised at the speed floor) within RK4's stability
(:func:`stable_substeps`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from rkmpc.control.linear.lmpc_id import with_rate_limit
from rkmpc.control.nonlinear.models import dynamic_ode
from rkmpc.control.nonlinear.nmpc import DynamicNMPC
from rkmpc.control.nonlinear.settings import NMPCConfig
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.estimation.steering import SteeringModel
from rkmpc.learning.identified_model import IdentifiedModel
from rkmpc.learning.tyre_model import IdentifiedTyres
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.control.settings import ControllerSettings
    from rkmpc.track.reference import Reference

__all__ = ["MAX_SUBSTEPS", "REAL_TIME", "IdentifiedDynamicNMPC", "stable_substeps"]

#: What the car's NMPC settings become for ``nmpc-id``: one SQP iteration per period.
REAL_TIME: dict[str, Any] = {"solver": "sqpmethod", "max_iterations": 1}
#: RK4 steps per period at most (each costs NLP time); stiffer tyres than this allows are refused.
MAX_SUBSTEPS = 8
#: ``|h lambda|`` an RK4 step may take (its stability region reaches 2.78 on the real axis).
_RK4_REACH = 2.5


def stable_substeps(vehicle: VehicleParams, tyres: IdentifiedTyres, dt: float, speed: float) -> int:
    """RK4 steps per period ``dt`` (s) that keep the lateral modes at ``speed`` (m/s) stable.

    The side-slip and yaw-rate dynamics of the single-track model with the curves' initial
    stiffnesses (static loads), linearised at ``speed``; at least ``DynamicNMPC.default_substeps``.

    Raises
    ------
    ParameterError
        When more than :data:`MAX_SUBSTEPS` would be needed (tyres no car has).
    """
    m, iz, lf, lr, g = vehicle.mass, vehicle.yaw_inertia, vehicle.lf, vehicle.lr, vehicle.gravity
    length = lf + lr
    cf = tyres.front.stiffness * m * g * lr / length
    cr = tyres.rear.stiffness * m * g * lf / length
    a = np.array(
        [
            [-(cf + cr) / (m * speed), (lr * cr - lf * cf) / (m * speed**2) - 1.0],
            [(lr * cr - lf * cf) / iz, -(lf**2 * cf + lr**2 * cr) / (iz * speed)],
        ]
    )
    fastest = float(np.max(np.abs(np.linalg.eigvals(a))))
    needed = max(DynamicNMPC.default_substeps, math.ceil(dt * fastest / _RK4_REACH))
    if needed > MAX_SUBSTEPS:
        raise ParameterError(
            f"nmpc-id: the identified tyres (stiffness {tyres.front.stiffness:.3g} / "
            f"{tyres.rear.stiffness:.3g} per unit load) make lateral modes of {fastest:.0f} 1/s at "
            f"{speed:g} m/s, {needed} RK4 steps per period (at most {MAX_SUBSTEPS})"
        )
    return needed


class IdentifiedDynamicNMPC(DynamicNMPC):
    """Dynamic single-track NMPC on identified tyres and servo.

    Parameters
    ----------
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        The car's nominal parameters (chassis, speed loop, limits).
    model : IdentifiedModel
        The identified servo and tyres (``model.tyres`` must be set).
    config : NMPCConfig, optional
        Weights, horizon and solver (as given: :meth:`from_settings` makes it real-time).
    min_speed : float, optional
        Speed floor (m/s) of the model's slip denominators (see :class:`DynamicNMPC`).

    Raises
    ------
    ParameterError
        When the model has no tyres.
    """

    name = "nmpc-id"

    @classmethod
    def from_settings(
        cls, reference: Reference, vehicle: VehicleParams, settings: ControllerSettings, model: object = None
    ) -> IdentifiedDynamicNMPC:
        model = cls.require_model(model)
        if not isinstance(model, IdentifiedModel):
            raise ParameterError(f"nmpc-id needs an IdentifiedModel, got {type(model).__name__}")
        return cls(reference, vehicle, model, replace(settings.nmpc, **REAL_TIME))

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        model: IdentifiedModel,
        config: NMPCConfig | None = None,
        min_speed: float | None = None,
    ) -> None:
        if model.tyres is None:
            raise ParameterError(
                "nmpc-id needs an identified model with tyres (`rkmpc train --kind identified-tyres`); "
                "this one has none"
            )
        self.model = model
        self.tyres: IdentifiedTyres = model.tyres
        self.servo = _servo(model, model.tyres.servo, vehicle)
        planned = with_rate_limit(vehicle, self.servo.rate_limit)
        lag = self.servo.time_constant + self.servo.delay
        planned = replace(planned, steering=replace(planned.steering, time_constant=lag))
        config = config if config is not None else NMPCConfig()
        if config.substeps is None:
            floor = float(vehicle.blend_speed_high if min_speed is None else min_speed)
            config = replace(config, substeps=stable_substeps(vehicle, self.tyres, config.dt, floor))
        super().__init__(reference, planned, config, min_speed)

    def _steering(self, vehicle: VehicleParams) -> SteeringModel:
        return self.servo

    def _wheel_measurement(self, observation: Observation) -> float:
        return math.nan if self.tyres.wheel == "commands" else observation.steer_angle

    def _ode(self) -> Any:
        return dynamic_ode(self.vehicle, self.min_speed, tyres=self.tyres.tyres(self.vehicle.mu))

    def _initial_state(self, observation: Observation, yaw: float) -> np.ndarray:
        state = super()._initial_state(observation, yaw)
        if not math.isfinite(observation.slip_angle) and math.isfinite(observation.yaw_rate):
            v, r = max(state[3], self.min_speed), observation.yaw_rate
            stiffness = self.tyres.rear.stiffness
            state[4] = math.atan(self.vehicle.lr * r / v - v * r / (self.vehicle.gravity * stiffness))
            state[3] = max(observation.speed, 0.0) / max(math.cos(state[4]), 0.1)
        return state


def _servo(model: IdentifiedModel, source: str, vehicle: VehicleParams) -> SteeringModel:
    """The servo the tyres were identified with (:data:`~rkmpc.learning.tyre_model.SERVO_SOURCES`), as
    identification ran it (:func:`~rkmpc.learning.identification.wheel_from_commands`: without a
    fitted rate limit, the car's own)."""
    if source == "nominal":
        return SteeringModel.nominal(vehicle)
    servo = SteeringModel.from_identified(model, vehicle.steering.max_angle)
    if servo.rate_limit is None:
        servo = replace(servo, rate_limit=vehicle.steering.max_rate)
    return replace(servo, delay=0.0) if source == "lag" else servo
