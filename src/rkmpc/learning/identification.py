"""Physical identification from on-track data: the steering servo and the understeer gradient.

This is what a skeptical engineer identifies from the same laps before reaching
for a neural network: how the front wheel follows the steering command, and
how much more wheel angle than the kinematic one the car needs in a corner.

Servo: the structure (first-order lag; delay and lag; delay and rate limit;
delay, lag and rate limit) is chosen by fit, see :mod:`rkmpc.learning.servo_fit`.
Understeer: one least-squares gradient, bounded to a plausible range.

Identification never raises on data that are finite and long enough. When a
fit is poor or not supported by the data, the nominal model of that part is
kept (the car's nominal servo lag, no understeer) or the parameter is held at
its bound, and :attr:`IdentifiedModel.warnings` says so in words (also emitted
as :class:`~rkmpc.core.errors.IdentificationWarning`).

The understeer model is defined once, here, and used both by the fit and by the
controller that drives with it (``lmpc-id``): the path curvature a wheel angle
``delta`` produces at speed ``v`` is ``tan(delta) / (L + K v^2)``
(:func:`effective_wheelbase`), so steady cornering on curvature ``kappa`` needs
``delta = atan((L + K v^2) kappa)`` (:func:`steady_state_steer`), and on data the
part of ``tan(delta)`` beyond the kinematic ``L r / v`` is ``K v r``
(:func:`understeer_excess`).
"""

from __future__ import annotations

import math
import numbers
import warnings
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.core.validation import is_integer
from rkmpc.learning.servo_fit import (
    MAX_DELAY,
    SERVO_MIN_R2,
    SERVO_STRUCTURES,
    ServoFit,
    fit_servo,
    history_depth,
    r_squared,
)
from rkmpc.vehicle.params import VehicleParams

__all__ = [
    "MIN_TRANSITIONS",
    "RATE_LIMIT_RANGE",
    "SERVO_STRUCTURE_NAMES",
    "TIME_CONSTANT_RANGE",
    "UNDERSTEER_MIN_R2",
    "UNDERSTEER_RANGE",
    "IdentifiedModel",
    "command_history",
    "effective_wheelbase",
    "identify",
    "steady_state_steer",
    "understeer_excess",
]

#: Columns of the observation arrays.
_SPEED, _YAW_RATE, _STEER = (OBSERVATION_FIELDS.index(n) for n in ("speed", "yaw_rate", "steer_angle"))

#: Transitions each fit needs at least.
MIN_TRANSITIONS = 20
#: Servo structures a model may name: the fitted ones, and ``nominal`` (the car's own lag, kept).
SERVO_STRUCTURE_NAMES: tuple[str, ...] = (*(s.name for s in SERVO_STRUCTURES), "nominal")
#: Plausible understeer gradients K (rad of extra wheel angle per m/s^2 of lateral acceleration,
#: that is s^2/m), about -11 to +56 deg/g: a factor of ten beyond what road cars (+1 to +4 deg/g)
#: and model cars show, either way. K is a wheel angle per lateral acceleration, so the range
#: does not depend on the size of the car. Besides, the car cannot have been beyond its critical
#: speed ``sqrt(-L / K)`` in its own data: K >= -L / (2 v_max^2), v_max the fastest speed fitted.
UNDERSTEER_RANGE = (-0.02, 0.1)
#: Range of servo time constants (s) an identified model may hold: a factor beyond the fit's own
#: search range (5 ms to 1 s, :data:`~rkmpc.learning.servo_fit.SERVO_PARAMETERS`) either way, so the
#: nominal lag of any real car fits too. Checked on every model, also one read from a file.
TIME_CONSTANT_RANGE = (1e-3, 2.0)
#: Range of servo rate limits (rad/s) an identified model may hold (the fit searches 0.1 to 20).
RATE_LIMIT_RANGE = (0.01, 100.0)
#: An understeer fit explaining less than this share of the excess wheel angle is not used.
UNDERSTEER_MIN_R2 = 0.3
#: RMS wheel-angle change per period (rad) below which the servo is not excited enough to fit.
_MIN_WHEEL_MOTION = 1e-3
#: RMS lateral acceleration (m/s^2) below which the understeer gradient is not identifiable.
_MIN_LATERAL_ACCELERATION = 0.2


class _Transitions(Protocol):
    @property
    def obs(self) -> np.ndarray: ...
    @property
    def command(self) -> np.ndarray: ...
    @property
    def next_obs(self) -> np.ndarray: ...
    @property
    def dt(self) -> float: ...
    @property
    def episode(self) -> np.ndarray: ...


@dataclass(frozen=True)
class IdentifiedModel:
    """The steering servo and the understeer gradient identified from data.

    Parameters
    ----------
    servo_time_constant : float
        First-order time constant of the steering servo (s), > 0.
    understeer_gradient : float
        ``K`` (s^2/m, that is rad per m/s^2): the effective wheelbase grows as
        ``L + K v^2``, so steady cornering needs ``tan(delta) = (L + K v^2) kappa``
        (:func:`steady_state_steer`); for small angles, the extra wheel angle per unit
        lateral acceleration.
    servo_fit_r2, understeer_fit_r2 : float
        Coefficients of determination of the best servo fit (one-step wheel-angle
        changes, whether it was kept or replaced by the nominal lag) and of the
        understeer gradient kept; NaN (None in JSON) when the data allowed no fit.
    n_samples : int
        Transitions the servo was fitted on: a finite wheel angle before and after, and
        the commands known back to the longest delay.
    servo_structure : str
        One of :data:`SERVO_STRUCTURE_NAMES`: the structure chosen, or ``nominal`` when
        the car's nominal lag was kept.
    servo_delay : float
        Pure delay of the servo (s), >= 0.
    servo_rate_limit : float or None
        Largest wheel rate (rad/s), None when the servo showed none.
    warnings : tuple of str
        What identification could not support and what it did instead, in words.

    Raises
    ------
    ParameterError
        Naming the field, for a value no car has (a hand-edited file): a time constant beyond
        :data:`TIME_CONSTANT_RANGE`, a gradient beyond :data:`UNDERSTEER_RANGE`, a delay beyond
        ``[0, MAX_DELAY]`` or a rate limit beyond :data:`RATE_LIMIT_RANGE`.
    """

    servo_time_constant: float
    understeer_gradient: float
    servo_fit_r2: float
    understeer_fit_r2: float
    n_samples: int
    servo_structure: str = "lag"
    servo_delay: float = 0.0
    servo_rate_limit: float | None = None
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        def number(value: object) -> bool:
            return isinstance(value, numbers.Real) and not isinstance(value, bool)

        name = "IdentifiedModel"

        def check_range(field: str, value: object, bounds: tuple[float, float], unit: str) -> None:
            low, high = bounds
            if not (number(value) and low <= float(value) <= high):  # type: ignore[arg-type]
                raise ParameterError(
                    f"{name}.{field} must be a number in [{low:g}, {high:g}] {unit} (plausible for a car), "
                    f"got {value!r}"
                )

        check_range("servo_time_constant", self.servo_time_constant, TIME_CONSTANT_RANGE, "s")
        check_range("understeer_gradient", self.understeer_gradient, UNDERSTEER_RANGE, "s^2/m")
        for field in ("servo_fit_r2", "understeer_fit_r2"):
            value = getattr(self, field)
            if value is None:  # JSON's null: no fit was made
                object.__setattr__(self, field, math.nan)
            elif not number(value):
                raise ParameterError(f"{name}.{field} must be a number or None, got {value!r}")
        if not is_integer(self.n_samples, 0):
            raise ParameterError(f"{name}.n_samples must be an integer >= 0, got {self.n_samples!r}")
        if self.servo_structure not in SERVO_STRUCTURE_NAMES:
            raise ParameterError(
                f"{name}.servo_structure must be one of {SERVO_STRUCTURE_NAMES}, got {self.servo_structure!r}"
            )
        check_range("servo_delay", self.servo_delay, (0.0, MAX_DELAY), "s")
        if self.servo_rate_limit is not None:
            check_range("servo_rate_limit", self.servo_rate_limit, RATE_LIMIT_RANGE, "rad/s")
        if not isinstance(self.warnings, (tuple, list)) or not all(isinstance(w, str) for w in self.warnings):
            raise ParameterError(f"{name}.warnings must be a sequence of strings, got {self.warnings!r}")
        object.__setattr__(self, "warnings", tuple(self.warnings))


def identify(data: _Transitions, vehicle: VehicleParams, *, min_speed: float = 1.0) -> IdentifiedModel:
    """Identify the steering servo and the understeer gradient of ``vehicle`` from ``data``.

    Parameters
    ----------
    data : TransitionDataset
        Transitions with measured wheel angle and yaw rate (observation columns
        ``steer_angle`` and ``yaw_rate``), grouped in episodes.
    vehicle : VehicleParams
        The car's nominal parameters: wheelbase L (m), and the servo time constant (s)
        kept when the servo cannot be identified.
    min_speed : float
        Transitions slower than this (m/s) are left out of the understeer fit.

    Returns
    -------
    IdentifiedModel
        With a warning for every part kept nominal or held at a bound.

    Raises
    ------
    ParameterError
        With fewer than :data:`MIN_TRANSITIONS` transitions that have a finite wheel
        angle before and after and enough commands before them in their episode.

    Notes
    -----
    Servo: every structure of :mod:`rkmpc.learning.servo_fit` is fitted to the one-step
    wheel-angle changes and the one of lowest BIC among those off their implausible bounds
    is kept, unless its R^2 is below ``SERVO_MIN_R2`` (0.5), all of them end on a bound, or
    the wheel barely moves: then the nominal lag ``vehicle.steering.time_constant``.

    Understeer: ``tan(delta_k) - L r_k / v_k = K v_k r_k`` by least squares
    (:func:`understeer_excess` against lateral acceleration), the model
    :func:`steady_state_steer` drives with. A fit with R^2 below
    :data:`UNDERSTEER_MIN_R2`, or too few fast samples, or too little cornering, gives
    ``K = 0`` (the kinematic model); a K beyond :data:`UNDERSTEER_RANGE` (the constrained
    least-squares solution) is held at the bound.
    """
    obs, nxt, cmd = np.asarray(data.obs), np.asarray(data.next_obs), np.asarray(data.command)
    steer, steer_next = obs[:, _STEER], nxt[:, _STEER]
    commands = command_history(cmd[:, 1], np.asarray(data.episode), history_depth(data.dt))
    ok = np.isfinite(steer) & np.isfinite(steer_next) & np.isfinite(commands).all(axis=1)
    if ok.sum() < MIN_TRANSITIONS:
        raise ParameterError(
            f"identify: needs at least {MIN_TRANSITIONS} transitions with a finite wheel angle before "
            f"and after and {commands.shape[1] - 1} commands before them in their episode, "
            f"got {int(ok.sum())}"
        )
    servo, servo_notes = _servo(
        steer[ok], steer_next[ok], commands[ok], data.dt, vehicle.steering.time_constant
    )
    speed, yaw_rate = obs[:, _SPEED], obs[:, _YAW_RATE]
    fast = np.isfinite(steer) & np.isfinite(yaw_rate) & np.isfinite(speed) & (speed > min_speed)
    gradient, understeer_r2, understeer_notes = _understeer(
        steer[fast], speed[fast], yaw_rate[fast], vehicle.wheelbase, min_speed
    )
    notes = (*servo_notes, *understeer_notes)
    for note in notes:
        warnings.warn(note, IdentificationWarning, stacklevel=2)
    return IdentifiedModel(
        servo_time_constant=servo.time_constant,
        understeer_gradient=gradient,
        servo_fit_r2=servo.r2,
        understeer_fit_r2=understeer_r2,
        n_samples=int(ok.sum()),
        servo_structure=servo.structure,
        servo_delay=servo.delay,
        servo_rate_limit=servo.rate_limit,
        warnings=notes,
    )


def command_history(command: np.ndarray, episode: np.ndarray, depth: int) -> np.ndarray:
    """``[u_k, u_{k-1}, ..., u_{k-depth}]`` of each transition, NaN before its episode starts.

    Parameters
    ----------
    command : numpy.ndarray
        One command per transition, shape (N,).
    episode : numpy.ndarray
        Episode id per transition, shape (N,); consecutive transitions of an episode are
        consecutive in time.
    depth : int
        Past commands wanted.

    Returns
    -------
    numpy.ndarray
        Shape (N, depth + 1).
    """
    n = len(command)
    out = np.full((n, depth + 1), np.nan)
    for j in range(min(depth, n - 1) + 1):
        column = out[j:, j]
        column[:] = command[: n - j]
        column[episode[j:] != episode[: n - j]] = np.nan
    return out


def _nominal(time_constant: float, r2: float) -> ServoFit:
    return ServoFit("nominal", time_constant, 0.0, None, r2, math.nan, ())


def _servo(
    delta: np.ndarray, delta_next: np.ndarray, commands: np.ndarray, dt: float, nominal: float
) -> tuple[ServoFit, list[str]]:
    """The servo to keep and the warnings: the best fit, or the nominal lag when none is usable."""
    keep = f"using the nominal first-order lag of {nominal:g} s"
    change = delta_next - delta
    motion = float(np.std(change))
    if motion < _MIN_WHEEL_MOTION:
        return _nominal(nominal, math.nan), [
            f"servo: the wheel angle barely moves ({motion:.1e} rad per period RMS, less than "
            f"{_MIN_WHEEL_MOTION:g}): not identifiable; {keep}"
        ]
    fits = fit_servo(delta, delta_next, commands, dt)
    usable = [f for f in fits if not f.at_bound]
    if not usable:
        bounds = "; ".join(f"{f.structure}: {', '.join(f.at_bound)}" for f in fits)
        return _nominal(nominal, fits[0].r2), [
            f"servo: every candidate structure ends on an implausible bound ({bounds}); {keep}"
        ]
    best = usable[0]
    if best.r2 < SERVO_MIN_R2:
        return _nominal(nominal, best.r2), [
            f"servo: the best fit ({best.structure}) explains R^2 = {best.r2:.2f} of the wheel-angle "
            f"changes, less than {SERVO_MIN_R2:g}; {keep}"
        ]
    return best, []


def _understeer(
    steer: np.ndarray, speed: np.ndarray, yaw_rate: np.ndarray, wheelbase: float, min_speed: float
) -> tuple[float, float, list[str]]:
    """Understeer gradient K, the R^2 of the K kept, and the warnings."""
    kinematic = "using K = 0 (the kinematic model)"
    if len(speed) < MIN_TRANSITIONS:
        return (
            0.0,
            math.nan,
            [
                f"understeer: only {len(speed)} transitions faster than {min_speed:g} m/s with a wheel angle "
                f"and a yaw rate (at least {MIN_TRANSITIONS}); {kinematic}"
            ],
        )
    excess = understeer_excess(steer, speed, yaw_rate, wheelbase)
    a_lat = speed * yaw_rate
    cornering = float(np.sqrt(np.mean(a_lat**2)))
    if cornering < _MIN_LATERAL_ACCELERATION:
        return (
            0.0,
            math.nan,
            [
                f"understeer: the car hardly corners ({cornering:.2f} m/s^2 lateral acceleration RMS, less "
                f"than {_MIN_LATERAL_ACCELERATION:g}): not identifiable; {kinematic}"
            ],
        )
    k = float(a_lat @ excess / (a_lat @ a_lat))
    r2 = r_squared(excess, k * a_lat)
    if r2 < UNDERSTEER_MIN_R2:
        return (
            0.0,
            r2,
            [
                f"understeer: the fit (K = {k:.4f} s^2/m) explains R^2 = {r2:.2f} of the excess wheel angle, "
                f"less than {UNDERSTEER_MIN_R2:g}; {kinematic}"
            ],
        )
    v_max = float(speed.max())
    lower = max(UNDERSTEER_RANGE[0], -0.5 * wheelbase / v_max**2)
    upper = UNDERSTEER_RANGE[1]
    if lower <= k <= upper:
        return k, r2, []
    bounded = min(max(k, lower), upper)
    return (
        bounded,
        r_squared(excess, bounded * a_lat),
        [
            f"understeer: the fit gives K = {k:.4f} s^2/m, beyond the plausible [{lower:.4f}, {upper:g}] "
            f"(rad per m/s^2; the lower end also keeps {v_max:.1f} m/s below the critical speed); "
            f"held at {bounded:g}"
        ],
    )


def effective_wheelbase(wheelbase: float, gradient: float, speed: np.ndarray) -> np.ndarray:
    """``L + K v^2`` (m): the wheelbase with which a kinematic model corners like the car at ``v`` (m/s)."""
    return wheelbase + gradient * speed * speed


def steady_state_steer(
    curvature: np.ndarray, speed: np.ndarray, wheelbase: float, gradient: float
) -> np.ndarray:
    """Wheel angle (rad) holding curvature ``kappa`` (1/m) at ``v`` (m/s): ``atan((L + K v^2) kappa)``."""
    return np.arctan(effective_wheelbase(wheelbase, gradient, speed) * curvature)


def understeer_excess(
    steer: np.ndarray, speed: np.ndarray, yaw_rate: np.ndarray, wheelbase: float
) -> np.ndarray:
    """``tan(delta) - L r / v``: the tangent of the wheel angle beyond the kinematic one (``K v r``)."""
    return np.tan(steer) - wheelbase * yaw_rate / speed
