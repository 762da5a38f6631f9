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


class ObservationDelay(PlantWrapper):
    """Odometry that arrives ``latency`` seconds late (a localisation filter's age).

    Each :meth:`step` is split into pieces of at most ``sample_period`` on the
    wrapped plant, and the observation after each piece is kept; :meth:`observe`
    returns the newest kept observation at least ``latency`` old (its ``time``
    is when it was true). Before ``latency`` has passed since :meth:`reset`, the
    observation of the reset state is returned. Wrap a plant whose commands act
    in time (an :class:`~rkmpc.vehicle.plants.base.ActuatedPlant`), not a
    :class:`CommandDelay`, which counts steps.

    Parameters
    ----------
    plant : Plant
        The plant to wrap.
    latency : float
        Age of every observation (s), >= 0; exact when a multiple of the
        pieces into which steps are split.
    sample_period : float, optional
        Longest piece (s), > 0.
    """

    def __init__(self, plant: Plant, latency: float, sample_period: float = 0.005) -> None:
        if not (math.isfinite(latency) and latency >= 0.0):
            raise ParameterError(f"ObservationDelay.latency must be finite and >= 0, got {latency!r}")
        if not (math.isfinite(sample_period) and sample_period > 0.0):
            raise ParameterError(
                f"ObservationDelay.sample_period must be finite and > 0, got {sample_period!r}"
            )
        super().__init__(plant)
        self.latency = float(latency)
        self.sample_period = float(sample_period)
        self._history: deque[Observation] = deque([plant.observe()])

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        super().reset(x, y, yaw, speed, steer)
        self._history = deque([self.plant.observe()])

    def step(self, command: Command, dt: float) -> None:
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        pieces = max(1, math.ceil(dt / self.sample_period - 1e-9))
        for _ in range(pieces):
            self.plant.step(command, dt / pieces)
            self._history.append(self.plant.observe())
        due = self.plant.time - self.latency + 1e-9
        history = self._history
        while len(history) > 1 and history[1].time <= due:
            history.popleft()

    def observe(self) -> Observation:
        return self._history[0]
