"""The one way to build a controller for a scenario: its car's settings, its model, checked once.

:func:`build_controller` takes the controller's settings from the scenario's car (planning with the
scenario's period), checks a learned model against the scenario (:func:`check_model`: the car, the
plant, the period, the wheelbase and the track scale it was made with) and builds the controller
(:func:`rkmpc.control.registry.make_controller`). The closed loop, the Gymnasium environment, the
studies and the ROS node all build their controllers here.
"""

from __future__ import annotations

from rkmpc.control.base import Controller
from rkmpc.control.registry import make_controller
from rkmpc.learning.contract import contract_of
from rkmpc.sim.scenario import Scenario

__all__ = ["build_controller", "check_model"]


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


def build_controller(
    name: str, scenario: Scenario, model: object = None, *, allow_mismatch: bool = False
) -> Controller:
    """The controller ``name`` for ``scenario``: the car's settings at its period, the model checked.

    Parameters
    ----------
    name : str
        A registered controller (:data:`rkmpc.control.registry.CONTROLLERS`).
    scenario : Scenario
        The track, the car (whose :class:`~rkmpc.control.settings.ControllerSettings` it reads)
        and the control period.
    model : optional
        The learned or identified model of a learned controller.
    allow_mismatch : bool
        Drive with a model made for another car or period anyway (with a warning).
    """
    if model is not None:
        check_model(model, scenario, source=f"the {name} model", allow_mismatch=allow_mismatch)
    settings = scenario.car.controllers.with_period(scenario.dt)
    return make_controller(name, scenario.reference, scenario.vehicle, settings=settings, model=model)
