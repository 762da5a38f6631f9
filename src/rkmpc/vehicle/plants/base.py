"""Common interface of the simulated cars ("plants") and their shared actuator machinery.

A :class:`Plant` is advanced one control period at a time with
:meth:`Plant.step`, holding a :class:`~rkmpc.core.observation.Command`, and reports
its true state through :meth:`Plant.observe`. Concrete plants:

* ``"f1tenth"`` -- :class:`rkmpc.vehicle.plants.dynamic.DynamicPlant` with
  :func:`rkmpc.vehicle.params.f1tenth` parameters;
* ``"fullsize"`` -- :class:`rkmpc.vehicle.plants.fullsize.FullSizePlant`, the
  CommonRoad drift model of a BMW 320i.

Use :func:`rkmpc.vehicle.registry.make_plant` to build one by name.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.vehicle.friction import FrictionSchedule
from rkmpc.vehicle.params import VehicleParams

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

    @property
    def unwrapped(self) -> Plant:
        """The innermost plant: this one (a wrapper returns the plant it wraps, all the way in)."""
        return self

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

    def _clamped_setpoint(self, setpoint: tuple[float, float]) -> tuple[float, float]:
        """``setpoint = (speed, steer)`` clipped to the drive's speed range (m/s) and steering limit (rad)."""
        drive = self.params.drive
        steering = self.params.steering
        v_cmd = min(max(setpoint[0], drive.min_speed), drive.max_speed)
        d_cmd = min(max(setpoint[1], -steering.max_angle), steering.max_angle)
        return v_cmd, d_cmd

    def _substeps(self, duration: float) -> list[float]:
        """Internal steps (s) covering ``duration`` (s): :attr:`internal_dt` each, the last one shorter."""
        h_nominal = self.internal_dt
        n_steps = max(1, math.ceil(duration / h_nominal - 1e-9))
        return [
            h_nominal if i < n_steps - 1 else duration - h_nominal * (n_steps - 1) for i in range(n_steps)
        ]

    @abstractmethod
    def _reset_state(self, x: float, y: float, yaw: float, speed: float, steer: float) -> None:
        """Set the state from validated reset values."""

    @abstractmethod
    def _advance(self, duration: float, setpoint: tuple[float, float]) -> None:
        """Integrate ``duration`` seconds from :attr:`time` holding ``setpoint = (speed, steer)``."""


def single_track_observation(
    x: float, y: float, yaw: float, v: float, beta: float, yaw_rate: float, delta: float, time: float
) -> Observation:
    """The true observation of a single-track state; ``speed`` is ``v cos(beta)``, along the heading.

    The state: position ``x, y`` (m) and speed magnitude ``v`` (m/s) of the centre of gravity,
    heading ``yaw`` (rad), side slip ``beta`` (rad), ``yaw_rate`` (rad/s), front wheel angle
    ``delta`` (rad), at simulation time ``time`` (s).
    """
    return Observation(
        x=x,
        y=y,
        yaw=yaw,
        speed=v * math.cos(beta),
        yaw_rate=yaw_rate,
        slip_angle=beta,
        steer_angle=delta,
        time=time,
    )


class SingleTrackPlant(ActuatedPlant):
    """An actuated plant with state ``[x, y, yaw, v, beta, yaw_rate, delta]`` (a list, :attr:`STATE_NAMES`).

    It starts on the kinematic circle of the reset wheel angle and reports
    :func:`single_track_observation`; subclasses integrate (:meth:`_advance`) and
    may reset parts of their own (:meth:`_reset_parts`).
    """

    STATE_NAMES: tuple[str, ...] = ("x", "y", "yaw", "v", "beta", "yaw_rate", "delta")
    _s: list[float]

    def _reset_state(self, x: float, y: float, yaw: float, speed: float, steer: float) -> None:
        length = self.params.wheelbase
        beta = math.atan(self.params.lr / length * math.tan(steer))
        yaw_rate = speed * math.cos(beta) * math.tan(steer) / length
        self._reset_parts(steer)
        self._s = [x, y, yaw, speed, beta, yaw_rate, steer]

    def _reset_parts(self, steer: float) -> None:
        """Hook: reset the plant's own parts to hold the wheel angle ``steer`` (rad)."""

    def observe(self) -> Observation:
        """True observation; ``speed`` is the velocity along the heading, ``v cos(beta)``."""
        x, y, yaw, v, beta, r, delta = self._s
        return single_track_observation(x, y, yaw, v, beta, r, delta, self._time)

    @property
    def state(self) -> np.ndarray:
        return np.array(self._s, dtype=float)

    @property
    def wheel_angle(self) -> float:
        return self._s[6]
