"""The one way to build a controller for a scenario: its car's settings, its model, checked once.

:func:`build_controller` takes the controller's settings from the scenario's car (planning with the
scenario's period), checks a learned model against the scenario (:func:`check_model`: the car, the
plant, the period, the wheelbase and the track scale it was made with) and builds the controller
(:func:`rkmpc.control.registry.make_controller`). Where the car's sensors do not measure every field
truthfully (a real car's profile, :mod:`rkmpc.vehicle.sensors`), the controller is stepped with the
state estimator's states (:class:`~rkmpc.control.estimated.EstimatedController`), whose wheel angle
follows the steering model the controller's model was trained with (:func:`steering_of`). The closed
loop, the Gymnasium environments, the studies and the ROS node all build their controllers here.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rkmpc.control.base import Controller
from rkmpc.control.estimated import EstimatedController
from rkmpc.control.registry import make_controller
from rkmpc.estimation.filter import StateEstimator
from rkmpc.estimation.labels import ESTIMATION_KEY
from rkmpc.estimation.steering import SteeringModel
from rkmpc.learning.contract import contract_of
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.params import VehicleParams

__all__ = ["build_controller", "check_model", "make_estimator", "steering_of"]


def check_model(
    model: object, scenario: Scenario, *, source: str, allow_mismatch: bool = False
) -> tuple[str, ...]:
    """Refuse a model made for another car, plant, period, wheelbase or track scale than ``scenario``'s.

    A model that records what it was made with (``metadata_`` holding a contract,
    :mod:`rkmpc.learning.contract`) is checked; one that records nothing is not.

    Returns
    -------
    tuple of str
        The warnings of allowed mismatches (``allow_mismatch``), for the caller to record.

    Raises
    ------
    ContractError
        On a mismatch, unless ``allow_mismatch``.
    """
    metadata = getattr(model, "metadata_", None)
    if not isinstance(metadata, dict):
        return ()
    return contract_of(metadata).check(
        scenario.provenance(), source=source, made="trained", allow_mismatch=allow_mismatch
    )


def steering_of(model: object, vehicle: VehicleParams) -> SteeringModel:
    """The steering model whose wheel angle a controller with ``model`` must be given.

    A model trained on estimated data records the steering model its wheel-angle feature was
    propagated with (:func:`rkmpc.estimation.labels.estimate_dataset`); an identified model is one;
    else the car's nominal servo.
    """
    if isinstance(model, IdentifiedModel):
        return SteeringModel.from_identified(model, vehicle.steering.max_angle)
    metadata: Any = getattr(model, "metadata_", None)
    data = metadata["data_metadata"] if isinstance(metadata, dict) and "data_metadata" in metadata else {}
    estimation = data[ESTIMATION_KEY] if isinstance(data, dict) and ESTIMATION_KEY in data else None
    if isinstance(estimation, dict) and "steering" in estimation:
        return SteeringModel.from_json(estimation["steering"])
    return SteeringModel.nominal(vehicle)


def make_estimator(scenario: Scenario, model: object = None) -> StateEstimator:
    """The state estimator of the scenario's car at its period, the wheel angle as ``model`` needs it."""
    config = replace(scenario.car.estimator, control_period=scenario.dt)
    return StateEstimator(scenario.vehicle, config, steering_of(model, scenario.vehicle))


def build_controller(
    name: str, scenario: Scenario, model: object = None, *, allow_mismatch: bool = False
) -> Controller:
    """The controller ``name`` for ``scenario``: the car's settings at its period, the model checked.

    Parameters
    ----------
    name : str
        A registered controller (:data:`rkmpc.control.registry.CONTROLLERS`).
    scenario : Scenario
        The track, the car (whose :class:`~rkmpc.control.settings.ControllerSettings` it reads, and
        whose sensors decide whether a state estimator stands in front of it) and the period.
    model : optional
        The learned or identified model of a learned controller.
    allow_mismatch : bool
        Drive with a model made for another car or period anyway (with a warning).
    """
    if model is not None:
        check_model(model, scenario, source=f"the {name} model", allow_mismatch=allow_mismatch)
    settings = scenario.car.controllers.with_period(scenario.dt)
    controller = make_controller(name, scenario.reference, scenario.vehicle, settings=settings, model=model)
    if scenario.car.sensors.is_ideal:
        return controller
    return EstimatedController(controller, make_estimator(scenario, model))
