"""The simulated car's physics clock: fixed physics steps, an actuation delay, and a way to stop.

:class:`PhysicsPlant` wraps any plant for ``rkmpc sim-node``. Each :meth:`PhysicsPlant.step`
integrates in steps of ``physics_dt`` (100 Hz, as the F1TENTH simulator), holding the command
that acts at each instant: a command given at ``t`` acts from ``t + actuation_delay`` (zero-order
hold). It also ends the run, by raising :class:`SimulationStopped`, when ``stop_reason`` says so
(Ctrl-C, a controller that stopped answering): :func:`rkmpc.sim.closed_loop.simulate` ends the
run on that error and keeps its log, which is how the node ends a run it drives through it.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

from rkmpc.core.errors import ParameterError, PlantIntegrationError
from rkmpc.core.observation import Command
from rkmpc.vehicle.plants.base import Plant, check_command
from rkmpc.vehicle.wrappers import PlantWrapper

__all__ = ["PhysicsPlant", "SimulationStopped"]

_EPS = 1e-9


class SimulationStopped(PlantIntegrationError):
    """The simulated car was stopped from outside (the message says why)."""


class PhysicsPlant(PlantWrapper):
    """A plant integrated in fixed physics steps, behind a timed actuation delay.

    Parameters
    ----------
    plant : Plant
        The car.
    physics_dt : float
        Physics step (s), > 0; every step is split into whole physics steps (at least one).
    actuation_delay : float
        Time (s) from a command being given to the car acting on it, >= 0.
    stop_reason : callable
        Called before every step; a non-empty string ends the run with :class:`SimulationStopped`.
    """

    def __init__(
        self,
        plant: Plant,
        *,
        physics_dt: float,
        actuation_delay: float = 0.0,
        stop_reason: Callable[[], str | None] = lambda: None,
    ) -> None:
        if not (math.isfinite(physics_dt) and physics_dt > 0.0):
            raise ParameterError(f"physics_dt must be finite and > 0, got {physics_dt!r}")
        if not (math.isfinite(actuation_delay) and actuation_delay >= 0.0):
            raise ParameterError(f"actuation_delay must be finite and >= 0, got {actuation_delay!r}")
        super().__init__(plant)
        self.physics_dt = float(physics_dt)
        self.actuation_delay = float(actuation_delay)
        self.stop_reason = stop_reason
        self._queue: deque[tuple[float, Command]] = deque()
        self.active = Command(0.0, 0.0)

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        super().reset(x, y, yaw, speed, steer)
        self._queue.clear()
        self.active = Command(float(speed), float(steer))

    def step(self, command: Command, dt: float) -> None:
        reason = self.stop_reason()
        if reason:
            raise SimulationStopped(reason, self.time)
        check_command(command)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        self._queue.append((self.time + self.actuation_delay, command))
        pieces = max(1, round(dt / self.physics_dt))
        for _ in range(pieces):
            now = self.plant.time
            while self._queue and self._queue[0][0] <= now + _EPS:
                self.active = self._queue.popleft()[1]
            self.plant.step(self.active, dt / pieces)
