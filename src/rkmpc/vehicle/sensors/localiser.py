"""The running state of a :class:`~rkmpc.vehicle.sensors.components.Localiser` in a simulation.

:class:`LocaliserRun` keeps what a localiser remembers between samples: the next
sample instant on its clock, the jump that is still decaying, and the samples in
flight (taken, not yet arrived). :class:`rkmpc.vehicle.sensors.profile.SensedPlant`
steps the wrapped plant to each sample instant and asks for the newest arrived sample.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

from rkmpc.core.observation import Observation
from rkmpc.vehicle.sensors.components import Localiser

__all__ = ["TIME_EPS", "LocaliserRun", "PoseSample"]

#: Two instants closer than this (s) count as the same instant.
TIME_EPS = 1e-9


class PoseSample(NamedTuple):
    """One localiser sample: the instant it was taken (s, plant clock) and what it reports."""

    instant: float
    x: float
    y: float
    yaw: float
    pose_time: float


class LocaliserRun:
    """The running state of a :class:`Localiser`: next sample instant, the decaying jump, samples in flight.

    Every sample draws, in this order and whatever the settings: three standard
    normals (along-track, cross-track, heading noise), three uniforms (jump or
    not, jump direction, interval to the next sample) and one standard
    exponential (jump excess), so changing one setting does not shift the
    random numbers of the others.
    """

    def __init__(self, spec: Localiser, rng: np.random.Generator) -> None:
        self.spec = spec
        self.rng = rng
        self.next_instant = math.nan
        self._origin = math.nan
        self._tick = 0
        self._offset = (0.0, 0.0)
        self._last_instant = math.nan
        self._in_flight: deque[PoseSample] = deque()

    def sample(self, instant: float, true: Observation) -> None:
        """Take a sample of the pose ``true`` at ``instant`` (s) and schedule the next one.

        The first sample sets the origin of the sample clock.
        """
        spec = self.spec
        if not math.isfinite(self._origin):
            self._origin = instant
        normal = self.rng.standard_normal(3)
        uniform = self.rng.random(3)
        excess = float(self.rng.standard_exponential())
        ox, oy = self._offset
        if math.isfinite(self._last_instant) and spec.jump_recovery > 0.0:
            decay = math.exp(-(instant - self._last_instant) / spec.jump_recovery)
            ox, oy = ox * decay, oy * decay
        else:
            ox, oy = 0.0, 0.0
        if uniform[0] < spec.jump_probability:
            size = spec.jump_min + spec.jump_mean_excess * excess
            direction = 2.0 * math.pi * float(uniform[1])
            ox, oy = ox + size * math.cos(direction), oy + size * math.sin(direction)
        self._offset = (ox, oy)
        self._last_instant = instant
        along = spec.along_track_std * float(normal[0])
        cross = spec.cross_track_std * float(normal[1])
        cos_yaw, sin_yaw = math.cos(true.yaw), math.sin(true.yaw)
        self._in_flight.append(
            PoseSample(
                instant=instant,
                x=true.x + along * cos_yaw - cross * sin_yaw + ox,
                y=true.y + along * sin_yaw + cross * cos_yaw + oy,
                yaw=true.yaw + spec.heading_std * float(normal[2]),
                pose_time=true.time,
            )
        )
        low, high = spec.interval_ticks
        self._tick += min(low + int((high - low + 1) * float(uniform[2])), high)
        self.next_instant = self._origin + self._tick * spec.resolution

    def newest_arrived(self, now: float) -> PoseSample:
        """The newest sample that has arrived by ``now`` (s); the first sample counts as arrived."""
        flight = self._in_flight
        due = now - self.spec.latency + TIME_EPS
        while len(flight) > 1 and flight[1].instant <= due:
            flight.popleft()
        return flight[0]
