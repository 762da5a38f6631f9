"""The fault interface: a change of the simulated car that the controllers are not told about."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import asdict
from typing import Any, ClassVar

from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.plants.base import Plant


class Fault(ABC):
    """A change of the simulated car that the controllers are not told about.

    Attributes
    ----------
    name : str
        The fault's name in :data:`FAULTS`.
    changes_car : bool
        True for a change of the car itself (its grip, its mass): applied to the car's plant,
        which its sensors then measure. False for a change of the signals between car and
        controller (measurement noise, a command delay): applied to what the controller sees and
        commands, after the sensors (the default).
    """

    name: ClassVar[str]
    changes_car: ClassVar[bool] = False

    @abstractmethod
    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        """Return the faulty version of ``plant``; ``plant`` itself is not changed.

        Parameters
        ----------
        plant : Plant
            The nominal plant of ``scenario``: the car itself (:meth:`Scenario.make_car_plant`)
            for a fault that :attr:`changes_car`, else the car seen through its sensors.
        scenario : Scenario
            The scenario (track, control period) the plant drives in.
        seed : int
            The run's seed; every random choice of the fault is drawn from it.

        Returns
        -------
        Plant
            A wrapper around ``plant``, or a new plant (reset to the origin) of
            the same kind and options.

        Raises
        ------
        ParameterError
            If the fault cannot apply to this plant or scenario.
        """

    def describe(self) -> dict[str, Any]:
        """JSON-ready record of the fault: ``{"name": ..., "parameters": {...}}``."""
        return {"name": self.name, "parameters": asdict(self)}  # type: ignore[call-overload]
