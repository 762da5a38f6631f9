"""A test-only plant wrapper that measures like a real F1TENTH car (no wheel angle, no slip angle).

The pose comes from a localiser at an irregular rate (20-40 Hz), late (30-60 ms), noisy and with
occasional jumps; the speed from the motor controller, scaled and noisy; the yaw rate from a gyro,
biased and noisy. Seeded: the same seed gives the same measurements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.core.observation import Observation
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.wrappers import PlantWrapper


@dataclass(frozen=True)
class Faults:
    """What the sensors get wrong (SI units)."""

    position_std: float = 0.03
    yaw_std: float = 0.02
    rate_hz: tuple[float, float] = (20.0, 40.0)
    latency_s: tuple[float, float] = (0.03, 0.06)
    jump_probability: float = 0.01
    jump_m: float = 1.2
    speed_scale: float = 1.15
    speed_std: float = 0.05
    gyro_bias: float = 0.05
    gyro_std: float = 0.03


class RealSensors(PlantWrapper):
    """``plant`` seen through the sensors of :class:`Faults`.

    Attributes
    ----------
    jumps : int
        Poses measured with a jump so far (some are superseded before they are delivered).
    delivered : list of Observation
        Every observation handed out since the last reset.
    """

    def __init__(self, plant: Plant, faults: Faults, seed: int) -> None:
        super().__init__(plant)
        self.faults = faults
        self.seed = seed
        self._restart()

    def _restart(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._history: list[tuple[float, float, float, float]] = []
        self._next_measure = 0.0
        self._pending: list[tuple[float, tuple[float, float, float, float]]] = []
        self._pose = (math.nan, math.nan, math.nan, math.nan)
        self.jumps = 0
        self.delivered: list[Observation] = []

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        super().reset(x, y, yaw, speed, steer)
        self._restart()

    def _true_pose(self, when: float) -> tuple[float, float, float]:
        times = [h[0] for h in self._history]
        return tuple(float(np.interp(when, times, [h[i] for h in self._history])) for i in (1, 2, 3))  # type: ignore[return-value]

    def observe(self) -> Observation:
        true = self.plant.observe()
        f, rng = self.faults, self._rng
        t = true.time
        self._history.append((t, true.x, true.y, true.yaw))
        # The localiser measures on its own clock and delivers each pose after its latency.
        while self._next_measure <= t:
            x, y, yaw = self._true_pose(self._next_measure)
            x += f.position_std * rng.standard_normal()
            y += f.position_std * rng.standard_normal()
            yaw += f.yaw_std * rng.standard_normal()
            if rng.random() < f.jump_probability:
                angle = rng.uniform(-math.pi, math.pi)
                size = rng.uniform(0.3, 1.0) * f.jump_m
                x, y = x + size * math.cos(angle), y + size * math.sin(angle)
                self.jumps += 1
            ready = self._next_measure + rng.uniform(*f.latency_s)
            self._pending.append((ready, (x, y, yaw, self._next_measure)))
            self._next_measure += 1.0 / rng.uniform(*f.rate_hz)
        while self._pending and self._pending[0][0] <= t:
            self._pose = self._pending.pop(0)[1]
        x, y, yaw, measured = self._pose
        if not math.isfinite(x):  # nothing delivered yet: the first pose, as it is, now
            x, y, yaw, measured = true.x, true.y, true.yaw, t
        observation = Observation(
            x,
            y,
            yaw,
            f.speed_scale * true.speed + f.speed_std * rng.standard_normal(),
            true.yaw_rate + f.gyro_bias + f.gyro_std * rng.standard_normal(),
            math.nan,
            math.nan,
            t,
            measured,
        )
        self.delivered.append(observation)
        return observation
