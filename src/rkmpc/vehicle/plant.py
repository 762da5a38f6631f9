"""Common interface of the simulated cars ("plants"), friction schedules and the plant registry.

A :class:`Plant` is advanced one control period at a time with
:meth:`Plant.step`, holding a :class:`~rkmpc.control.base.Command`, and reports
its true state through :meth:`Plant.observe`. Concrete plants:

* ``"f1tenth"`` -- :class:`rkmpc.vehicle.dynamic.DynamicPlant` with
  :func:`rkmpc.vehicle.params.f1tenth` parameters;
* ``"fullsize"`` -- :class:`rkmpc.vehicle.fullsize.FullSizePlant`, the
  CommonRoad drift model of a BMW 320i.

Use :func:`make_plant` to build one by name.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rkmpc.control.base import Command, Observation
from rkmpc.errors import ParameterError
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.path import Path

# Two instants closer than this (s) count as the same instant.
_TIME_EPS = 1e-9


class Plant(ABC):
    """A simulated car driven by speed and wheel-angle set-points.

    Attributes
    ----------
    params : VehicleParams
        Parameters of the car (wheelbase, actuator limits, ...).
    STATE_NAMES : tuple of str
        Names of the components of :attr:`state`, in order.
    """

    params: VehicleParams
    STATE_NAMES: tuple[str, ...] = ()

    @abstractmethod
    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        """Place the car, driving steadily, and set the clock to zero.

        Parameters
        ----------
        x, y : float
            Position of the centre of gravity (m).
        yaw : float
            Heading (rad).
        speed : float
            Speed (m/s), >= 0.
        steer : float, optional
            Front wheel angle (rad); the car starts on the kinematic circle of
            this angle and holds ``Command(speed, steer)`` until told otherwise.
        """

    @abstractmethod
    def step(self, command: Command, dt: float) -> None:
        """Advance ``dt`` seconds holding ``command`` (after the plant's input delay).

        Parameters
        ----------
        command : Command
            Speed (m/s) and front wheel angle (rad) set-points.
        dt : float
            Duration (s), typically one control period, > 0.
        """

    @abstractmethod
    def observe(self) -> Observation:
        """Return the true (noise-free) observation at the current time."""

    @property
    @abstractmethod
    def state(self) -> np.ndarray:
        """Copy of the full state, shape ``(len(STATE_NAMES),)``, ordered as :attr:`STATE_NAMES`."""

    @property
    @abstractmethod
    def time(self) -> float:
        """Simulation time since the last :meth:`reset` (s)."""

    @property
    @abstractmethod
    def wheel_angle(self) -> float:
        """Actual front wheel angle (rad), after the steering servo."""


# --------------------------------------------------------------------------- friction


@dataclass(frozen=True)
class CircularRegion:
    """A disc of the plane where a friction change applies.

    Parameters
    ----------
    center : tuple of float
        Centre ``(x, y)`` (m).
    radius : float
        Radius (m), > 0.
    """

    center: tuple[float, float]
    radius: float

    def __post_init__(self) -> None:
        if len(self.center) != 2 or not all(math.isfinite(c) for c in self.center):
            raise ParameterError(f"CircularRegion.center must be two finite numbers, got {self.center!r}")
        if not (math.isfinite(self.radius) and self.radius > 0.0):
            raise ParameterError(f"CircularRegion.radius must be finite and > 0, got {self.radius!r}")

    def contains(self, x: float, y: float) -> bool:
        """Whether the point ``(x, y)`` (m) lies in the disc (boundary included)."""
        dx = x - self.center[0]
        dy = y - self.center[1]
        return dx * dx + dy * dy <= self.radius * self.radius


class FrictionSchedule(ABC):
    """A friction multiplier as a function of time and position.

    The plant multiplies its nominal friction coefficient by
    ``schedule(time, x, y)`` at every internal integration step.
    """

    @abstractmethod
    def __call__(self, time: float, x: float, y: float) -> float:
        """Friction multiplier (-) at ``time`` (s) and position ``(x, y)`` (m)."""


@dataclass(frozen=True)
class FrictionChange(FrictionSchedule):
    """Multiply the friction by ``factor`` during a time window, optionally only inside a region.

    Parameters
    ----------
    factor : float
        Friction multiplier (-), > 0 (e.g. 0.6 for a wet patch).
    start_time : float, optional
        Time the change begins (s), inclusive.
    end_time : float, optional
        Time the change ends (s), exclusive; ``inf`` for never.
    region : CircularRegion or None, optional
        Where it applies; everywhere when None.
    """

    factor: float
    start_time: float = 0.0
    end_time: float = math.inf
    region: CircularRegion | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.factor) and self.factor > 0.0):
            raise ParameterError(f"FrictionChange.factor must be finite and > 0, got {self.factor!r}")
        if math.isnan(self.start_time) or math.isnan(self.end_time) or self.end_time <= self.start_time:
            raise ParameterError(
                f"FrictionChange needs start_time < end_time, got {self.start_time!r}, {self.end_time!r}"
            )

    def __call__(self, time: float, x: float, y: float) -> float:
        if not self.start_time <= time < self.end_time:
            return 1.0
        if self.region is not None and not self.region.contains(x, y):
            return 1.0
        return self.factor


class ArcWindowFriction(FrictionSchedule):
    """Multiply the friction by ``factor`` over a stretch of track given by arc length.

    A point is in the stretch when its projection onto ``path`` (nearest path
    point over the whole lap) has arc length in ``[start_s, start_s + length_s)``,
    wrapping across ``s = 0``, and lies at most ``max_lateral`` from the path.
    The multiplier does not depend on time. Points outside the bounding box of
    the stretch are rejected before projecting, so the schedule costs a
    projection only near the stretch.

    Parameters
    ----------
    factor : float
        Friction multiplier (-) inside the stretch, finite and > 0.
    path : Path
        The path whose arc length defines the stretch (usually the track's
        centre line).
    start_s : float
        Arc length where the stretch begins (m); wrapped into ``[0, path.length)``.
    length_s : float
        Length of the stretch along the path (m), ``0 < length_s <= path.length``.
    max_lateral : float
        Largest distance from the path (m) that still counts as on the
        stretch, finite and > 0 (e.g. twice the track's half-width).
    """

    def __init__(
        self, factor: float, path: Path, start_s: float, length_s: float, max_lateral: float
    ) -> None:
        if not (math.isfinite(factor) and factor > 0.0):
            raise ParameterError(f"ArcWindowFriction.factor must be finite and > 0, got {factor!r}")
        if not math.isfinite(start_s):
            raise ParameterError(f"ArcWindowFriction.start_s must be finite, got {start_s!r}")
        if not (math.isfinite(length_s) and 0.0 < length_s <= path.length):
            raise ParameterError(
                f"ArcWindowFriction.length_s must be in (0, {path.length!r}] (the lap), got {length_s!r}"
            )
        if not (math.isfinite(max_lateral) and max_lateral > 0.0):
            raise ParameterError(f"ArcWindowFriction.max_lateral must be finite and > 0, got {max_lateral!r}")
        self.factor = float(factor)
        self.path = path
        self.start_s = float(start_s) % path.length
        self.length_s = float(length_s)
        self.max_lateral = float(max_lateral)
        # Bounding box of the stretch widened by max_lateral and by the sample spacing
        # (the path cannot leave the box of its samples by more than one spacing).
        n = min(100_000, max(100, math.ceil(self.length_s / (0.1 * self.max_lateral)) + 1))
        xy = path.position(self.start_s + np.linspace(0.0, self.length_s, n))
        pad = self.max_lateral + self.length_s / (n - 1)
        self._box = (
            float(xy[:, 0].min()) - pad,
            float(xy[:, 0].max()) + pad,
            float(xy[:, 1].min()) - pad,
            float(xy[:, 1].max()) + pad,
        )

    def contains(self, x: float, y: float) -> bool:
        """Whether the point ``(x, y)`` (m) lies on the stretch."""
        x0, x1, y0, y1 = self._box
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            return False
        proj = self.path.project(x, y)
        if abs(proj.lateral) > self.max_lateral:
            return False
        return (proj.s - self.start_s) % self.path.length < self.length_s

    def __call__(self, time: float, x: float, y: float) -> float:
        return self.factor if self.contains(x, y) else 1.0

    def __repr__(self) -> str:
        return (
            f"ArcWindowFriction(factor={self.factor!r}, start_s={self.start_s!r}, "
            f"length_s={self.length_s!r}, max_lateral={self.max_lateral!r})"
        )


@dataclass(frozen=True)
class FrictionProduct(FrictionSchedule):
    """The product of several friction schedules (each change acts on top of the others).

    Parameters
    ----------
    schedules : tuple of FrictionSchedule
        The factors, at least one.
    """

    schedules: tuple[FrictionSchedule, ...]

    def __post_init__(self) -> None:
        if not self.schedules:
            raise ParameterError("FrictionProduct needs at least one schedule")

    def __call__(self, time: float, x: float, y: float) -> float:
        factor = 1.0
        for schedule in self.schedules:
            factor *= schedule(time, x, y)
        return factor


def combine_friction(*schedules: FrictionSchedule | None) -> FrictionSchedule | None:
    """The product of the given schedules, ignoring None; None when all are None.

    A single schedule is returned as it is.
    """
    present = tuple(s for s in schedules if s is not None)
    if not present:
        return None
    if len(present) == 1:
        return present[0]
    return FrictionProduct(present)


# --------------------------------------------------------------------------- shared plant machinery


def check_command(command: Command) -> tuple[float, float]:
    """Return ``(speed, steer)`` of a command as floats; ValueError if not finite."""
    speed = float(command.speed)
    steer = float(command.steer)
    if not (math.isfinite(speed) and math.isfinite(steer)):
        raise ValueError(f"command must be finite, got speed={command.speed!r}, steer={command.steer!r}")
    return speed, steer


class _DelayLine:
    """Timed queue of set-points: a command pushed at ``t`` takes effect at ``t + delay``."""

    def __init__(self, delay: float) -> None:
        self.delay = delay
        self.active: tuple[float, float] = (0.0, 0.0)
        self._pending: deque[tuple[float, tuple[float, float]]] = deque()

    def clear(self, active: tuple[float, float]) -> None:
        self.active = active
        self._pending.clear()

    def push(self, now: float, setpoint: tuple[float, float]) -> None:
        self._pending.append((now + self.delay, setpoint))

    def activate(self, now: float) -> None:
        """Make the latest set-point due by ``now`` the active one."""
        pending = self._pending
        while pending and pending[0][0] <= now + _TIME_EPS:
            self.active = pending.popleft()[1]

    def switch_times(self, start: float, end: float) -> list[float]:
        """Instants strictly inside ``(start, end)`` where a queued set-point takes effect."""
        return [t for t, _ in self._pending if start + _TIME_EPS < t < end - _TIME_EPS]


class ActuatedPlant(Plant):
    """Base of plants with a delayed command line and a friction schedule.

    Subclasses implement :meth:`_reset_state` and :meth:`_advance`;
    :meth:`step` splits each period at the instants where delayed commands
    take effect, so a delay need not be a multiple of the control period.

    Parameters
    ----------
    params : VehicleParams
        Car parameters.
    internal_dt : float
        Internal integration step (s), > 0.
    input_delay : float
        Delay between :meth:`step` receiving a command and the actuators
        seeing it (s), >= 0.
    friction : FrictionSchedule or None
        Friction multiplier schedule; None for constant ``params.mu``.
    """

    def __init__(
        self,
        params: VehicleParams,
        *,
        internal_dt: float,
        input_delay: float,
        friction: FrictionSchedule | None,
    ) -> None:
        if not (math.isfinite(internal_dt) and internal_dt > 0.0):
            raise ParameterError(f"internal_dt must be finite and > 0, got {internal_dt!r}")
        if not (math.isfinite(input_delay) and input_delay >= 0.0):
            raise ParameterError(f"input_delay must be finite and >= 0, got {input_delay!r}")
        self.params = params
        self.internal_dt = float(internal_dt)
        self.input_delay = float(input_delay)
        self.friction = friction
        self._time = 0.0
        self._delay = _DelayLine(self.input_delay)
        self.reset(0.0, 0.0, 0.0, 0.0, 0.0)

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        values = (x, y, yaw, speed, steer)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"reset values must be finite, got {values!r}")
        if speed < 0.0:
            raise ValueError(f"reset speed must be >= 0, got {speed!r}")
        if abs(steer) > self.params.steering.max_angle:
            raise ValueError(
                f"reset steer {steer!r} exceeds the steering limit {self.params.steering.max_angle!r} rad"
            )
        self._time = 0.0
        self._delay.clear((float(speed), float(steer)))
        self._reset_state(float(x), float(y), float(yaw), float(speed), float(steer))

    def step(self, command: Command, dt: float) -> None:
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        self._delay.push(self._time, check_command(command))
        start = self._time
        end = start + dt
        self._delay.activate(start)
        for boundary in [*self._delay.switch_times(start, end), end]:
            self._advance(boundary - self._time, self._delay.active)
            self._time = boundary
            self._delay.activate(boundary)

    @property
    def time(self) -> float:
        return self._time

    def friction_factor(self, time: float, x: float, y: float) -> float:
        """Friction multiplier (-) of the schedule, 1 when there is none."""
        if self.friction is None:
            return 1.0
        return float(self.friction(time, x, y))

    @abstractmethod
    def _reset_state(self, x: float, y: float, yaw: float, speed: float, steer: float) -> None:
        """Set the state from validated reset values."""

    @abstractmethod
    def _advance(self, duration: float, setpoint: tuple[float, float]) -> None:
        """Integrate ``duration`` seconds from :attr:`time` holding ``setpoint = (speed, steer)``."""


# --------------------------------------------------------------------------- registry


def _make_f1tenth(**options: Any) -> Plant:
    from rkmpc.vehicle.dynamic import DynamicPlant
    from rkmpc.vehicle.params import f1tenth

    params = options.pop("params", None) or f1tenth()
    return DynamicPlant(params, **options)


def _make_fullsize(**options: Any) -> Plant:
    from rkmpc.vehicle.fullsize import FullSizePlant

    return FullSizePlant(**options)


#: Plant factories by name; each accepts the plant's keyword options.
PLANTS: dict[str, Callable[..., Plant]] = {
    "f1tenth": _make_f1tenth,
    "fullsize": _make_fullsize,
}


def make_plant(name: str, **options: Any) -> Plant:
    """Build a registered plant.

    Parameters
    ----------
    name : str
        A key of :data:`PLANTS` (``"f1tenth"``, ``"fullsize"``).
    **options
        Keyword options of the plant's constructor (``internal_dt``,
        ``input_delay``, ``friction``; ``params`` for ``"f1tenth"``).

    Returns
    -------
    Plant
        The plant, reset to the origin at standstill.

    Raises
    ------
    ValueError
        If ``name`` is not registered.
    """
    try:
        factory = PLANTS[name]
    except KeyError:
        known = ", ".join(sorted(PLANTS))
        raise ValueError(f"unknown plant {name!r}; known plants: {known}") from None
    return factory(**options)
