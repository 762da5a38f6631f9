"""What the benchmark scripts share: a scenario whose car drives with other controller settings."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rkmpc.sim.scenario import Scenario

__all__ = ["with_controllers"]


def with_controllers(scenario: Scenario, **sections: Any) -> Scenario:
    """``scenario`` whose car has the given sections of its controller settings replaced.

    ``sections`` are fields of :class:`rkmpc.control.settings.ControllerSettings` (``rkmpc=RKMPCConfig(...)``,
    ``nmpc=...``); the track, the reference and everything else of the car stay.
    """
    if not sections:
        return scenario
    car = scenario.car
    return replace(scenario, car=replace(car, controllers=replace(car.controllers, **sections)))
