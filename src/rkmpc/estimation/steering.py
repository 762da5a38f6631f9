"""The front wheel angle of a car without a steering sensor: a servo model driven by the commands sent.

One continuous-time servo (the model of :mod:`rkmpc.learning.servo_fit`),

    d delta / dt = clip((u(t - d) - delta) / tau, -R, R),

with the command ``u`` clipped to the wheel's largest angle and held over each control period
``T`` (zero-order hold), a pure delay ``d``, a lag ``tau`` and an optional rate limit ``R``.
:class:`SteeringModel` holds the parameters: the car's nominal servo
(:meth:`SteeringModel.nominal`) or an identified one (:meth:`SteeringModel.from_identified`).

:class:`WheelAnglePropagator` integrates it exactly, one control period per call, from the
command sent at the period before; :func:`wheel_angles` does the same over a recorded command
array, with the same arithmetic, so both give bit-identical angles. Without a rate limit the
model is linear and a step is the exact discretisation
:func:`rkmpc.learning.servo_fit.lag_delay_weights`, ``delta_{k+1} = a delta_k + sum_j w_j u_{k-j}``;
with one, the exact piecewise solution of :func:`rkmpc.learning.servo_fit.servo_step`, written
here on plain floats (``servo_step`` takes some 60 us a call on arrays, too slow for a control step;
the tests check both agree).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.learning.servo_fit import delay_periods, lag_delay_weights
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.learning.identification import IdentifiedModel

__all__ = ["STEERING_STRUCTURES", "SteeringModel", "WheelAnglePropagator", "wheel_angles"]

#: The structures a :class:`SteeringModel` can have, by which of delay and rate limit it holds.
STEERING_STRUCTURES: tuple[str, ...] = ("lag", "delay-lag", "lag-rate", "delay-lag-rate")


@dataclass(frozen=True, kw_only=True)
class SteeringModel:
    """A steering servo: lag, optional delay, optional rate limit, and the wheel's largest angle.

    Parameters
    ----------
    time_constant : float
        Lag ``tau`` of the servo (s), finite and > 0.
    max_angle : float
        Largest wheel angle magnitude (rad), > 0; commands are clipped to it (``inf``: no clip).
    delay : float
        Pure delay ``d`` between a command and the servo seeing it (s), finite and >= 0.
    rate_limit : float or None
        Largest wheel rate ``R`` (rad/s), > 0; None for none.
    source : str
        Where the parameters come from, in words (``"nominal"``, ``"identified (delay-lag)"``).

    Raises
    ------
    ParameterError
        Naming the field, for a value outside its range.
    """

    time_constant: float
    max_angle: float
    delay: float = 0.0
    rate_limit: float | None = None
    source: str = "given"

    def __post_init__(self) -> None:
        def check(name: str, value: Any, low: float, strict: bool, finite: bool = True) -> None:
            number = isinstance(value, int | float) and not isinstance(value, bool)
            ok = number and (value > low if strict else value >= low) and (math.isfinite(value) or not finite)
            if not ok:
                sign = ">" if strict else ">="
                kind = "finite and " if finite else ""
                raise ParameterError(f"SteeringModel.{name} must be {kind}{sign} {low:g}, got {value!r}")

        check("time_constant", self.time_constant, 0.0, strict=True)
        check("max_angle", self.max_angle, 0.0, strict=True, finite=False)
        if isinstance(self.max_angle, float) and math.isnan(self.max_angle):
            raise ParameterError(f"SteeringModel.max_angle must be > 0, got {self.max_angle!r}")
        check("delay", self.delay, 0.0, strict=False)
        if self.rate_limit is not None:
            check("rate_limit", self.rate_limit, 0.0, strict=True)
        if not isinstance(self.source, str):
            raise ParameterError(f"SteeringModel.source must be a string, got {self.source!r}")

    @property
    def structure(self) -> str:
        """One of :data:`STEERING_STRUCTURES`: ``lag`` with ``delay-`` and ``-rate`` where they apply."""
        prefix = "delay-" if self.delay > 0.0 else ""
        suffix = "-rate" if self.rate_limit is not None else ""
        return f"{prefix}lag{suffix}"

    @classmethod
    def nominal(cls, params: VehicleParams) -> SteeringModel:
        """The car's own servo (:class:`~rkmpc.vehicle.params.SteeringParams`): lag, rate limit, no delay.

        This is the servo the simulated plants integrate, so the propagated angle follows theirs.
        """
        s = params.steering
        return cls(
            time_constant=s.time_constant,
            max_angle=s.max_angle,
            rate_limit=s.max_rate,
            source=f"nominal ({params.name})",
        )

    @classmethod
    def from_identified(cls, model: IdentifiedModel, max_angle: float = math.inf) -> SteeringModel:
        """The servo of an identified model: its time constant, delay and rate limit (if any).

        Parameters
        ----------
        model : IdentifiedModel
            From :func:`rkmpc.learning.identification.identify`; a model whose structure is
            ``nominal`` (the fit was not used) holds the car's nominal lag.
        max_angle : float
            The wheel's largest angle (rad); the model file does not hold it (default: no clip).
        """
        return cls(
            time_constant=float(model.servo_time_constant),
            max_angle=max_angle,
            delay=float(model.servo_delay),
            rate_limit=None if model.servo_rate_limit is None else float(model.servo_rate_limit),
            source=f"identified ({model.servo_structure})",
        )

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SteeringModel:
        """The model back from :meth:`describe`'s record (a model file's metadata keeps it)."""
        try:
            max_angle = data["max_angle_rad"]
            rate = data["rate_limit_rad_s"]
            return cls(
                time_constant=float(data["time_constant_s"]),
                max_angle=math.inf if max_angle is None else float(max_angle),
                delay=float(data["delay_s"]),
                rate_limit=None if rate is None else float(rate),
                source=str(data["source"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ParameterError(f"not a steering model record: {data!r} ({exc})") from None

    def describe(self) -> dict[str, Any]:
        """The parameters as a JSON-able dictionary (``max_angle`` and ``rate_limit`` None when absent)."""
        return {
            "structure": self.structure,
            "time_constant_s": self.time_constant,
            "delay_s": self.delay,
            "rate_limit_rad_s": self.rate_limit,
            "max_angle_rad": self.max_angle if math.isfinite(self.max_angle) else None,
            "source": self.source,
        }


def _hold(delta: float, target: float, duration: float, tau: float, rate: float) -> float:
    """Wheel angle (rad) after ``duration`` (s) of ``d delta/dt = clip((target - delta)/tau, -rate, rate)``.

    Exact: the wheel moves at the rate limit while the error exceeds ``rate * tau``, then decays.
    """
    gap = target - delta
    ramp = min(max((abs(gap) - rate * tau) / rate, 0.0), duration)
    moved = delta + math.copysign(rate * ramp, gap)
    return target - (target - moved) * math.exp(-(duration - ramp) / tau)


class WheelAnglePropagator:
    """The wheel angle of a :class:`SteeringModel`, advanced one control period per :meth:`step`.

    Call :meth:`step` once per control period with the steering command sent at the period
    before (None before the first). The first command seen is taken as held since long before:
    the commands before it equal it and, unless an initial angle was given to :meth:`reset`, the
    wheel starts settled at it.

    Parameters
    ----------
    model : SteeringModel
        The servo.
    dt : float
        Control period T (s), > 0: every command is held that long.

    Attributes
    ----------
    a : float
        ``exp(-T / tau)``, the lag's factor per period.
    weights : numpy.ndarray
        ``w_j`` of the commands ``u_{k}, u_{k-1}, ...`` of the linear (rate-unlimited) part
        (:func:`~rkmpc.learning.servo_fit.lag_delay_weights`).
    """

    def __init__(self, model: SteeringModel, dt: float) -> None:
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0.0):
            raise ParameterError(f"WheelAnglePropagator.dt must be finite and > 0, got {dt!r}")
        self.model = model
        self.dt = float(dt)
        self.a, self.weights = lag_delay_weights(model.time_constant, model.delay, self.dt)
        self._w = [float(w) for w in self.weights]
        whole = delay_periods(model.delay, self.dt)
        self._whole = whole
        self._rest = max(model.delay - whole * self.dt, 0.0)
        # The commands of the periods before, newest first: enough for the delay's two periods.
        self._depth = max(len(self._w), whole + 2)
        self._limit = model.max_angle
        self.reset()

    def reset(self, initial: float = math.nan) -> None:
        """Forget the commands and the angle; ``initial`` (rad, NaN: unknown) is the angle at the start."""
        self._angle = math.nan
        self._initial = float(initial)
        self._past = [0.0] * self._depth
        self._seen = False

    @property
    def angle(self) -> float:
        """The wheel angle (rad) as of the last :meth:`step`; NaN before the first."""
        return self._angle

    @property
    def past_commands(self) -> np.ndarray:
        """Commands ``[u_{k-1}, u_{k-2}, ...]`` (rad, clipped) as of the last step, shape (len(weights),).

        Before the first command, all equal to the first one seen (or zero).
        """
        return np.array(self._past[: len(self._w)])

    def step(self, steer_sent_last: float | None, measured: float = math.nan) -> float:
        """The wheel angle now (rad), one period after the previous call.

        Parameters
        ----------
        steer_sent_last : float or None
            The steering command (rad) sent at the previous period; None when none was sent yet.
        measured : float
            A measured wheel angle (rad) when the car has a sensor, NaN when not: a finite
            measurement is returned and the model continues from it.

        Returns
        -------
        float
        """
        if steer_sent_last is not None:
            limit = self._limit
            u = min(max(float(steer_sent_last), -limit), limit)
            if self._seen:
                self._past.insert(0, u)
                self._past.pop()
            else:
                self._past = [u] * self._depth
                self._seen = True
        elif self._seen:  # nothing sent this period: the servo holds the last command
            self._past.insert(0, self._past[0])
            self._past.pop()
        if math.isfinite(measured):
            self._angle = float(measured)
        elif math.isnan(self._angle):
            # The first angle: the given one, else settled at the first command, else straight.
            if math.isfinite(self._initial):
                self._angle = self._initial
            else:
                self._angle = self._past[0] if self._seen else 0.0
        elif self._seen:
            self._angle = self._advance(self._angle)
        return self._angle

    def _advance(self, delta: float) -> float:
        """One period of the servo from ``delta`` (rad) under the commands in ``_past``."""
        past = self._past
        rate = self.model.rate_limit
        if rate is None:
            out = self.a * delta
            for w, u in zip(self._w, past, strict=False):
                out += w * u
            return out
        tau, rest, whole = self.model.time_constant, self._rest, self._whole
        # The first ``rest`` seconds of the period still see the command one period older.
        mid = _hold(delta, past[whole + 1], rest, tau, rate) if rest > 0.0 else delta
        return _hold(mid, past[whole], self.dt - rest, tau, rate)


def wheel_angles(
    model: SteeringModel,
    dt: float,
    steer: np.ndarray,
    *,
    initial: float = math.nan,
    measured: np.ndarray | None = None,
) -> np.ndarray:
    """The wheel angles of a recorded command sequence, bit-identical to :class:`WheelAnglePropagator`.

    Parameters
    ----------
    model : SteeringModel
        The servo.
    dt : float
        Control period (s).
    steer : numpy.ndarray
        Steering commands (rad), shape (n,): ``steer[k]`` sent at period ``k`` and held over it.
    initial : float
        Wheel angle at the start (rad); NaN for unknown (straight ahead, the propagator's rule).
    measured : numpy.ndarray, optional
        Measured wheel angles (rad; NaN where none), shape (n + 1,).

    Returns
    -------
    numpy.ndarray
        Shape (n + 1,): entry 0 the angle at the start, entry ``k`` after ``steer[:k]``.
    """
    commands = np.asarray(steer, dtype=float).reshape(-1)
    meas = np.full(commands.size + 1, math.nan) if measured is None else np.asarray(measured, dtype=float)
    if meas.shape != (commands.size + 1,):
        raise ParameterError(
            f"wheel_angles: measured must have shape ({commands.size + 1},), got {meas.shape}"
        )
    propagator = WheelAnglePropagator(model, dt)
    propagator.reset(initial)
    out = np.empty(commands.size + 1)
    out[0] = propagator.step(None, float(meas[0]))
    for k, u in enumerate(commands.tolist()):
        out[k + 1] = propagator.step(u, float(meas[k + 1]))
    return out
