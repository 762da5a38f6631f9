"""Faults of the signals between car and controller: measurement noise and a command delay."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_positive_value
from rkmpc.sim.faults.base import Fault
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.wrappers import CommandDelay, NoiseStd, ObservationNoise

#: Measurement noise used by ``--noise`` and the ``"noise"`` fault (1-sigma):
#: 1 cm, 0.5 deg, 2 cm/s, 0.02 rad/s.
DEFAULT_NOISE = NoiseStd(position=0.01, yaw=0.0087, speed=0.02, yaw_rate=0.02)


@dataclass(frozen=True)
class NoiseFault(Fault):
    """Seeded Gaussian noise on the observed pose, speed and yaw rate.

    Effect: the controller sees ``observation + std * N(0, 1)`` per component
    (see :class:`~rkmpc.vehicle.wrappers.ObservationNoise`); the car itself,
    the logged true state and the errors measured against it are unchanged.
    The noise sequence is drawn from the run's seed.

    Parameters
    ----------
    std : NoiseStd, optional
        Standard deviations; :data:`DEFAULT_NOISE` by default.
    """

    name: ClassVar[str] = "noise"
    changes_car: ClassVar[bool] = False
    std: NoiseStd = DEFAULT_NOISE

    def __post_init__(self) -> None:
        if not isinstance(self.std, NoiseStd):
            raise ParameterError(f"NoiseFault.std must be a NoiseStd, got {self.std!r}")

    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        return ObservationNoise(plant, self.std, seed=seed)


@dataclass(frozen=True)
class DelayFault(Fault):
    """An extra actuation delay of a whole number of control periods.

    Effect: each command reaches the plant ``delay`` seconds later than it
    would nominally, on top of the plant's own input delay; for the first
    ``delay / dt`` steps the plant keeps the command of its reset (the
    flying-start set-point). Nothing else changes.

    Parameters
    ----------
    delay : float, optional
        Extra delay (s), > 0 and a whole multiple of the scenario's control
        period (checked in :meth:`apply`); 0.05 s, one period at 20 Hz, by default.
    """

    name: ClassVar[str] = "delay"
    changes_car: ClassVar[bool] = False
    delay: float = 0.05

    def __post_init__(self) -> None:
        require_positive_value(self.delay, "DelayFault.delay")

    def steps(self, dt: float) -> int:
        """The delay in control periods of ``dt`` seconds.

        Raises
        ------
        ParameterError
            If ``delay`` is not a whole multiple of ``dt``.
        """
        steps = round(self.delay / dt)
        if steps < 1 or abs(steps * dt - self.delay) > 1e-9 * max(1.0, self.delay):
            raise ParameterError(
                f"DelayFault.delay {self.delay!r} s is not a whole number of control periods (dt = {dt!r} s)"
            )
        return steps

    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        return CommandDelay(plant, self.steps(scenario.dt))
