"""Steering actuators and speed loops: the parts of a car between the set-point and the chassis.

Real cars differ most where the controller's command becomes motion. Each part
here is a frozen, validated description (what a data sheet or an
identification gives) with a ``build()`` that returns a fresh stateful
instance for one plant:

* steering actuators advance the front wheel angle one internal step ``h`` at a
  time, :meth:`SteeringActuator.advance`, so delays, rate-limited bang-bang
  servos and quantised positions are simulated exactly as they act;
* speed loops map the commanded and actual speed to the tangential
  acceleration, :meth:`SpeedLoopSpec.build` returns ``accel(v_cmd, v)``, which
  the plant integrates with the chassis.

The steering command reaching an actuator is already clipped to the car's
angle limit by the plant.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_nonnegative, require_positive

__all__ = [
    "AsymmetricSpeedLoop",
    "DelayedRateServo",
    "FirstOrderServo",
    "LagSpeedLoop",
    "QuantisedServo",
    "SecondOrderServo",
    "SpeedLoopSpec",
    "SteeringActuator",
    "SteeringSpec",
    "limit_accel",
]

# Two instants closer than this (s) are the same instant.
_TIME_EPS = 1e-9


class SteeringActuator(ABC):
    """A stateful steering actuator: wheel angle in response to the commanded angle."""

    @abstractmethod
    def reset(self, angle: float) -> None:
        """Hold ``angle`` (rad) at rest, as if it had been commanded forever."""

    @abstractmethod
    def advance(self, command: float, h: float) -> float:
        """Advance ``h`` seconds with ``command`` (rad) at the input; return the new wheel angle (rad)."""


class SteeringSpec(ABC):
    """Description of a steering actuator; :meth:`build` makes one for a plant."""

    @abstractmethod
    def build(self) -> SteeringActuator:
        """A fresh actuator at rest at angle 0."""


# --------------------------------------------------------------------------- first-order lag


@dataclass(frozen=True)
class FirstOrderServo(SteeringSpec):
    """First-order lag with a rate limit: ``deltadot = clip((cmd - delta) / tau, -rate, rate)``.

    Advanced with the exact step of the lag over ``h``, then limited to
    ``max_rate * h``. The project's own car and most hobby servos under a
    position loop (ForzaETH NUC2: ``tau`` = 0.158 s, 3.2 rad/s).

    Parameters
    ----------
    time_constant : float
        Lag time constant (s), > 0.
    max_rate : float
        Largest wheel-angle rate magnitude (rad/s), > 0.
    """

    time_constant: float
    max_rate: float

    def __post_init__(self) -> None:
        require_positive(self, "time_constant", "max_rate")

    def build(self) -> SteeringActuator:
        return _LagServo(self.time_constant, self.max_rate)


class _LagServo(SteeringActuator):
    def __init__(self, time_constant: float, max_rate: float) -> None:
        self.time_constant = time_constant
        self.max_rate = max_rate
        self._h = -1.0
        self._gain = 0.0
        self.angle = 0.0

    def reset(self, angle: float) -> None:
        self.angle = angle

    def advance(self, command: float, h: float) -> float:
        if h != self._h:
            self._h = h
            self._gain = -math.expm1(-h / self.time_constant)
        step = (command - self.angle) * self._gain
        limit = self.max_rate * h
        self.angle += min(max(step, -limit), limit)
        return self.angle


# --------------------------------------------------------------------------- delay + rate limit


@dataclass(frozen=True)
class DelayedRateServo(SteeringSpec):
    """Pure delay, then a wheel that always moves at its rate limit (bang-bang).

    Every ``update_period`` the servo looks at the command it received
    ``delay`` seconds earlier and chooses to turn left or right at
    ``max_rate`` (or to hold, if the wheel is exactly on it); between updates it
    keeps turning. So the wheel never settles: it limit-cycles about
    ``max_rate * update_period`` around a constant command. This is a
    position-loop servo with a coarse, saturated loop, as found by a team that
    probed its car with a step command (the issue's "different car").

    Parameters
    ----------
    delay : float
        Pure delay (s), >= 0.
    max_rate : float
        Wheel-angle rate while moving (rad/s), > 0.
    update_period : float
        Interval between direction decisions (s), > 0.
    """

    delay: float
    max_rate: float
    update_period: float = 0.01

    def __post_init__(self) -> None:
        require_nonnegative(self, "delay")
        require_positive(self, "max_rate", "update_period")

    def build(self) -> SteeringActuator:
        return _DelayedRateServo(self.delay, self.max_rate, self.update_period)


class _DelayedRateServo(SteeringActuator):
    def __init__(self, delay: float, max_rate: float, update_period: float) -> None:
        self.delay = delay
        self.max_rate = max_rate
        self.update_period = update_period
        self.angle = 0.0
        self._time = 0.0
        self._next_update = 0.0
        self._direction = 0.0
        self._delayed = 0.0
        self._queue: deque[tuple[float, float]] = deque()

    def reset(self, angle: float) -> None:
        self.angle = angle
        self._time = 0.0
        self._next_update = 0.0
        self._direction = 0.0
        self._delayed = angle
        self._queue.clear()

    def advance(self, command: float, h: float) -> float:
        queue = self._queue
        queue.append((self._time + self.delay, command))
        while queue and queue[0][0] <= self._time + _TIME_EPS:
            self._delayed = queue.popleft()[1]
        if self._time >= self._next_update - _TIME_EPS:
            error = self._delayed - self.angle
            self._direction = 0.0 if error == 0.0 else math.copysign(1.0, error)
            self._next_update += self.update_period
        self.angle += self._direction * self.max_rate * h
        self._time += h
        return self.angle


# --------------------------------------------------------------------------- second order


@dataclass(frozen=True)
class SecondOrderServo(SteeringSpec):
    """Second-order servo with overshoot: ``delta'' = wn^2 (cmd - delta) - 2 zeta wn delta'``.

    Advanced with the exact discretisation of the linear system over ``h``
    (matrix exponential); afterwards the wheel-angle rate is limited to
    ``max_rate``. With ``zeta`` < 1 a step overshoots by
    ``exp(-zeta pi / sqrt(1 - zeta^2))`` (16 % at ``zeta`` = 0.5), like a
    stiff, under-damped steering linkage.

    Parameters
    ----------
    natural_frequency : float
        ``wn`` (rad/s), > 0.
    damping : float
        ``zeta`` (-), > 0.
    max_rate : float
        Largest wheel-angle rate magnitude (rad/s), > 0.
    """

    natural_frequency: float
    damping: float
    max_rate: float

    def __post_init__(self) -> None:
        require_positive(self, "natural_frequency", "damping", "max_rate")

    def build(self) -> SteeringActuator:
        return _SecondOrderServo(self.natural_frequency, self.damping, self.max_rate)


class _SecondOrderServo(SteeringActuator):
    def __init__(self, natural_frequency: float, damping: float, max_rate: float) -> None:
        wn, zeta = natural_frequency, damping
        # x = [delta, delta_rate]; xdot = A x + b cmd.
        self._a = np.array([[0.0, 1.0], [-wn * wn, -2.0 * zeta * wn]])
        self._b = np.array([0.0, wn * wn])
        self.max_rate = max_rate
        # Exact discretisations by step length (a plant uses one or two lengths).
        self._steps: dict[float, tuple[float, float, float, float, float, float]] = {}
        self.angle = 0.0
        self.rate = 0.0

    def _discretise(self, h: float) -> tuple[float, float, float, float, float, float]:
        block = np.zeros((3, 3))
        block[:2, :2] = self._a * h
        block[:2, 2] = self._b * h
        e = expm(block)
        step = (
            float(e[0, 0]),
            float(e[0, 1]),
            float(e[1, 0]),
            float(e[1, 1]),
            float(e[0, 2]),
            float(e[1, 2]),
        )
        if len(self._steps) < 64:
            self._steps[h] = step
        return step

    def reset(self, angle: float) -> None:
        self.angle = angle
        self.rate = 0.0

    def advance(self, command: float, h: float) -> float:
        step = self._steps.get(h)
        a00, a01, a10, a11, b0, b1 = self._discretise(h) if step is None else step
        angle = a00 * self.angle + a01 * self.rate + b0 * command
        rate = a10 * self.angle + a11 * self.rate + b1 * command
        limit = self.max_rate
        if abs(rate) > limit:
            rate = math.copysign(limit, rate)
            angle = self.angle + rate * h
        self.angle, self.rate = angle, rate
        return angle


# --------------------------------------------------------------------------- quantised position


@dataclass(frozen=True)
class QuantisedServo(SteeringSpec):
    """Another actuator whose wheel angle only takes multiples of ``step``.

    The inner actuator runs on as if continuous; the wheel sits on the
    multiple of ``step`` nearest to it (the position resolution of a cheap
    servo: its PWM or potentiometer steps).

    Parameters
    ----------
    inner : SteeringSpec
        The actuator being quantised.
    step : float
        Angle resolution (rad), > 0.
    """

    inner: SteeringSpec
    step: float

    def __post_init__(self) -> None:
        require_positive(self, "step")
        if isinstance(self.inner, QuantisedServo):
            raise ParameterError("QuantisedServo.inner is already quantised")

    def build(self) -> SteeringActuator:
        return _QuantisedServo(self.inner.build(), self.step)


class _QuantisedServo(SteeringActuator):
    def __init__(self, inner: SteeringActuator, step: float) -> None:
        self.inner = inner
        self.step = step

    def reset(self, angle: float) -> None:
        self.inner.reset(angle)

    def advance(self, command: float, h: float) -> float:
        return round(self.inner.advance(command, h) / self.step) * self.step


# --------------------------------------------------------------------------- speed loops

#: ``accel(v_cmd, v)``: tangential acceleration (m/s^2) for the commanded and actual speed (m/s).
SpeedLoop = Callable[[float, float], float]


class SpeedLoopSpec(ABC):
    """Description of a speed loop; :meth:`build` returns its acceleration law."""

    @abstractmethod
    def build(self) -> SpeedLoop:
        """``accel(v_cmd, v)`` (m/s^2), never negative at standstill."""


def limit_accel(acc: float, v: float, max_accel: float, max_brake: float) -> float:
    """``acc`` (m/s^2) clipped to ``[-max_brake, max_accel]``; never negative at speed ``v <= 0`` (m/s)."""
    if acc > max_accel:
        acc = max_accel
    elif acc < -max_brake:
        acc = -max_brake
    if v <= 0.0 and acc < 0.0:
        acc = 0.0
    return acc


def _gain_law(up_gain: float, down_gain: float, max_accel: float, max_brake: float) -> SpeedLoop:
    def accel(v_cmd: float, v: float) -> float:
        error = v_cmd - v
        return limit_accel(up_gain * error if error > 0.0 else down_gain * error, v, max_accel, max_brake)

    return accel


@dataclass(frozen=True)
class LagSpeedLoop(SpeedLoopSpec):
    """First-order lag: ``a = clip((v_cmd - v) / tau, -max_brake, max_accel)``.

    Parameters
    ----------
    time_constant : float
        Lag time constant (s), > 0.
    max_accel, max_brake : float
        Acceleration and deceleration magnitude limits (m/s^2), > 0.
    """

    time_constant: float
    max_accel: float
    max_brake: float

    def __post_init__(self) -> None:
        require_positive(self, "time_constant", "max_accel", "max_brake")

    def build(self) -> SpeedLoop:
        gain = 1.0 / self.time_constant
        return _gain_law(gain, gain, self.max_accel, self.max_brake)


@dataclass(frozen=True)
class AsymmetricSpeedLoop(SpeedLoopSpec):
    """Proportional loop with its own gain for accelerating and for braking, and caps.

    ``a = k_up (v_cmd - v)`` when the car is too slow, ``k_down (v_cmd - v)``
    when too fast, clipped to ``[-max_brake, max_accel]``: a VESC in current
    mode, where the motor pulls harder than it brakes (or the reverse).

    Parameters
    ----------
    accel_gain, brake_gain : float
        ``k_up`` and ``k_down`` (1/s), > 0.
    max_accel, max_brake : float
        Acceleration and deceleration magnitude caps (m/s^2), > 0.
    """

    accel_gain: float
    brake_gain: float
    max_accel: float
    max_brake: float

    def __post_init__(self) -> None:
        require_positive(self, "accel_gain", "brake_gain", "max_accel", "max_brake")

    def build(self) -> SpeedLoop:
        return _gain_law(self.accel_gain, self.brake_gain, self.max_accel, self.max_brake)
