"""``nmpc-id``: the dynamic NMPC on what two laps identify, in real time.

:class:`~rkmpc.control.nonlinear.nmpc.DynamicNMPC` (``nmpc-dynamic``) is given the car's nominal
dynamic model: Pacejka tyres, servo and speed loop from the data sheet. ``nmpc-id`` is the same
NLP on the model identified from laps of the track (:func:`rkmpc.learning.learn.learn` with the
``identified-tyres`` recipe):

* the tyre curves of :mod:`rkmpc.learning.tyre_fit` (linear, Pacejka, or the nominal ones
  scaled; the nominal ones when nothing predicted better, marked so in the model). The
  understeer the kinematic fit identifies is not used: in a dynamic model it follows from the
  tyres (``K = (1 / c_f - 1 / c_r) / g``, reported beside it);
* the identified servo: its lag, with a pure delay folded into it (``tau + d``; the NLP's model
  is a first-order lag), and a rate limit, when one was identified, as the steering-step limit;
  the wheel angle the state starts from is run from the commands through the identified servo,
  delay included, when it is not measured or when the tyres were fitted on a wheel run that way;
* without a side-slip measurement, the side slip the state starts from is the steady-state one
  of the identified rear tyres, ``lr r / v - v r / (g c_r)`` (``nmpc-dynamic`` takes the
  kinematic one).

The chassis (mass, inertia, axle distances) and the speed loop are the car's nominal ones. Built
from a car's settings (:meth:`IdentifiedDynamicNMPC.from_settings`) it runs the real-time path:
one SQP iteration per period (:data:`REAL_TIME`), warm-started from the previous plan.
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

__all__ = ["REAL_TIME", "IdentifiedDynamicNMPC"]

#: What the car's NMPC settings become for ``nmpc-id``: one SQP iteration per period.
REAL_TIME: dict[str, Any] = {"solver": "sqpmethod", "max_iterations": 1}


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
        lag = model.servo_time_constant + model.servo_delay
        planned = with_rate_limit(vehicle, model.servo_rate_limit)
        planned = replace(planned, steering=replace(planned.steering, time_constant=lag))
        super().__init__(reference, planned, config, min_speed)

    def _steering(self, vehicle: VehicleParams) -> SteeringModel:
        # As identification ran it (wheel_from_commands): without a fitted rate limit, the car's own.
        servo = SteeringModel.from_identified(self.model, vehicle.steering.max_angle)
        return servo if servo.rate_limit is not None else replace(servo, rate_limit=vehicle.steering.max_rate)

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
