"""Plant wrappers: optional features layered around any :class:`~rkmpc.vehicle.plants.base.Plant`.

In the style of Gymnasium wrappers, each feature is a class that holds a plant
and forwards everything it does not change, so features compose by nesting
instead of by flags on the plants.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, fields, replace

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.core.validation import is_integer
from rkmpc.vehicle.plants.base import Plant, check_command


class PlantWrapper(Plant):
    """A plant that forwards every call to the wrapped ``plant``.

    Parameters
    ----------
    plant : Plant
        The plant to wrap (possibly itself a wrapper).
    """

    def __init__(self, plant: Plant) -> None:
        self.plant = plant
        self.params = plant.params
        self.STATE_NAMES = plant.STATE_NAMES

    @property
    def unwrapped(self) -> Plant:
        """The innermost plant."""
        inner = self.plant
        while isinstance(inner, PlantWrapper):
            inner = inner.plant
        return inner

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        self.plant.reset(x, y, yaw, speed, steer)

    def step(self, command: Command, dt: float) -> None:
        self.plant.step(command, dt)

    def observe(self) -> Observation:
        return self.plant.observe()

    @property
    def state(self) -> np.ndarray:
        return self.plant.state

    @property
    def time(self) -> float:
        return self.plant.time

    @property
    def wheel_angle(self) -> float:
        return self.plant.wheel_angle


@dataclass(frozen=True)
class NoiseStd:
    """Standard deviations of Gaussian measurement noise (SI units), all >= 0.

    Parameters
    ----------
    position : float, optional
        On each of ``x`` and ``y`` independently (m).
    yaw : float, optional
        On the heading (rad).
    speed : float, optional
        On the speed (m/s).
    yaw_rate : float, optional
        On the yaw rate (rad/s).
    """

    position: float = 0.0
    yaw: float = 0.0
    speed: float = 0.0
    yaw_rate: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"NoiseStd.{f.name} must be finite and >= 0, got {value!r}")


class ObservationNoise(PlantWrapper):
    """Add seeded Gaussian noise to the observations of a plant.

    Each :meth:`observe` draws five standard normal numbers, in the order
    ``x, y, yaw, speed, yaw_rate``, whatever the standard deviations, so
    changing one deviation does not change the noise sequence of the others.
    Side-slip and wheel angle are passed through unchanged. :meth:`reset`
    re-seeds the generator with ``seed``, so every episode started from the
    same state with the same commands sees the same noise.

    Parameters
    ----------
    plant : Plant
        The plant to wrap.
    std : NoiseStd
        Noise standard deviations.
    seed : int
        Seed of :func:`numpy.random.default_rng`.
    """

    def __init__(self, plant: Plant, std: NoiseStd, seed: int) -> None:
        super().__init__(plant)
        self.std = std
        self.seed = int(seed)
        self._rng = np.random.default_rng(self.seed)

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        super().reset(x, y, yaw, speed, steer)
        self._rng = np.random.default_rng(self.seed)

    def observe(self) -> Observation:
        true = self.plant.observe()
        noise = self._rng.standard_normal(5)
        std = self.std
        return replace(
            true,
            x=true.x + std.position * float(noise[0]),
            y=true.y + std.position * float(noise[1]),
            yaw=true.yaw + std.yaw * float(noise[2]),
            speed=true.speed + std.speed * float(noise[3]),
            yaw_rate=true.yaw_rate + std.yaw_rate * float(noise[4]),
        )


class CommandDelay(PlantWrapper):
    """Deliver each command to the wrapped plant a fixed number of steps late.

    The command given to the ``n``-th :meth:`step` reaches the wrapped plant
    at step ``n + steps``, that is ``steps`` control periods later when every
    step lasts one period. This delay adds to the plant's own input delay. For
    the first ``steps`` steps after :meth:`reset` the plant receives the
    command it was reset to hold, ``Command(speed, steer)`` of the reset (at
    construction, before any reset, ``Command(0, 0)``).

    Parameters
    ----------
    plant : Plant
        The plant to wrap.
    steps : int
        Delay in steps, >= 0; 0 passes every command straight through.
    """

    def __init__(self, plant: Plant, steps: int) -> None:
        if not is_integer(steps, 0):
            raise ParameterError(f"CommandDelay.steps must be an integer >= 0, got {steps!r}")
        super().__init__(plant)
        self.steps = int(steps)
        self._queue: deque[Command] = deque()
        self._fill(Command(0.0, 0.0))

    def _fill(self, command: Command) -> None:
        self._queue.clear()
        self._queue.extend([command] * self.steps)

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        super().reset(x, y, yaw, speed, steer)
        self._fill(Command(float(speed), float(steer)))

    def step(self, command: Command, dt: float) -> None:
        check_command(command)  # a bad command fails now, not ``steps`` steps later
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        self._queue.append(command)
        self.plant.step(self._queue.popleft(), dt)
