"""The steering servo's model: one continuous-time law, its exact steps, its parameter space.

Every candidate servo of identification is one model,

    d delta / dt = clip((u(t - d) - delta) / tau, -R, R),

with the command ``u`` held over each control period ``T`` (zero-order hold),
a pure delay ``d`` that may be a fraction of ``T``, a lag ``tau`` and a rate
limit ``R``. A structure (:data:`SERVO_STRUCTURES`) says which of the three
are fitted; the others keep their neutral value (no delay, the fastest lag the
data resolve, the car's nominal rate limit or none). :func:`servo_step`
integrates the model exactly over one period from a known wheel angle (the
one-step prediction of a measured wheel), :func:`simulate_servo` runs it over
whole episodes from the commands alone (the wheel angle a car without a
steering sensor had). Without a rate limit the model is linear and
:func:`lag_delay_weights` gives its exact discretisation, the one ``lmpc-id``
predicts with.

The parameter space of a fit (:class:`ServoParameter`) holds each parameter's
plausible range: :data:`SERVO_PARAMETERS` in absolute terms, and
:func:`vehicle_servo_parameters` relative to the servo of the car's data sheet,
so that a servo identification has not seen stays plausible (a rate limit at
most a factor :data:`RATE_LIMIT_FACTOR` from the nominal one). :func:`refine`
minimises a vectorised objective around a grid point of such a space.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MAX_DELAY",
    "RATE_LIMIT_FACTOR",
    "SERVO_PARAMETERS",
    "SERVO_STRUCTURES",
    "ServoParameter",
    "ServoStructure",
    "bound_hits",
    "delay_periods",
    "history_depth",
    "lag_delay_weights",
    "r_squared",
    "refine",
    "servo_step",
    "simulate_servo",
    "structure_grid",
    "structure_values",
    "vehicle_servo_parameters",
]

#: Largest plausible steering delay (s): six periods of a 20 Hz controller, twice the delay of the
#: shared real F1TENTH car (its command-turning correlation peaks three periods late).
MAX_DELAY = 0.3
#: An identified rate limit stays within this factor of the car's nominal one, either way: a servo
#: five times slower than its data sheet (0.64 against 3.2 rad/s) is a fit of something else.
RATE_LIMIT_FACTOR = 3.0
#: Stand-in for "no rate limit" (rad/s) inside the arithmetic.
_UNLIMITED = 1e6


@dataclass(frozen=True)
class ServoParameter:
    """One servo parameter: its plausible range and how it is searched.

    Parameters
    ----------
    name : str
        ``delay`` (s), ``time_constant`` (s) or ``rate_limit`` (rad/s).
    unit : str
        Unit, for messages.
    lower, upper : float
        Plausible range; a fit is searched only inside it.
    log : bool
        Searched on a logarithmic scale.
    grid : int
        Points of the coarse grid.
    neutral : float
        Value of a structure that does not fit it (no delay, the fastest lag, the nominal or no limit).
    lower_is_a_result : bool
        Whether a fit at the lower bound is a finding ("no delay", "faster than the data
        resolve") rather than a sign the structure is wrong.
    """

    name: str
    unit: str
    lower: float
    upper: float
    log: bool
    grid: int
    neutral: float
    lower_is_a_result: bool

    def value(self, z: np.ndarray) -> np.ndarray:
        """The parameter at unit coordinates ``z`` in [0, 1] (0 at ``lower``, 1 at ``upper``)."""
        if self.log:
            return self.lower * (self.upper / self.lower) ** z
        return self.lower + (self.upper - self.lower) * z


#: The three parameters of every candidate, with their plausible ranges in absolute terms: a
#: delay of up to :data:`MAX_DELAY`, a time constant of 5 ms (a fast digital servo) to 1 s (slower
#: than any car's steering), a wheel rate of 0.1 rad/s (slower than a road car's rack, about
#: 0.4 rad/s at the wheel) to 20 rad/s (faster than any servo the data at 20 Hz could show).
SERVO_PARAMETERS: dict[str, ServoParameter] = {
    p.name: p
    for p in (
        ServoParameter("delay", "s", 0.0, MAX_DELAY, log=False, grid=16, neutral=0.0, lower_is_a_result=True),
        ServoParameter(
            "time_constant", "s", 0.005, 1.0, log=True, grid=12, neutral=0.005, lower_is_a_result=True
        ),
        ServoParameter(
            "rate_limit", "rad/s", 0.1, 20.0, log=True, grid=8, neutral=math.inf, lower_is_a_result=False
        ),
    )
}


def vehicle_servo_parameters(max_rate: float, dt: float) -> dict[str, ServoParameter]:
    """The plausible servo of a car whose data sheet gives the wheel rate limit ``max_rate`` (rad/s).

    A delay of 0 to :data:`MAX_DELAY` on a grid of half a period; a lag from ``0.4 dt`` (s; a
    faster lag leaves less than 8 % of a step after one period, which a data set sampled every
    ``dt`` cannot tell from none) to 1 s; a rate limit within :data:`RATE_LIMIT_FACTOR` of
    ``max_rate``, which a structure that does not fit it keeps (the servo is as fast as its data
    sheet says).
    """
    half_periods = math.floor(MAX_DELAY / (dt / 2) + 1e-9) + 1
    return {
        "delay": ServoParameter(
            "delay", "s", 0.0, MAX_DELAY, log=False, grid=half_periods, neutral=0.0, lower_is_a_result=True
        ),
        "time_constant": ServoParameter(
            "time_constant", "s", 0.4 * dt, 1.0, log=True, grid=10, neutral=0.4 * dt, lower_is_a_result=True
        ),
        "rate_limit": ServoParameter(
            "rate_limit",
            "rad/s",
            max_rate / RATE_LIMIT_FACTOR,
            max_rate * RATE_LIMIT_FACTOR,
            log=True,
            grid=7,
            neutral=max_rate,
            lower_is_a_result=False,
        ),
    }


@dataclass(frozen=True)
class ServoStructure:
    """A candidate servo: which of ``delay``, ``time_constant``, ``rate_limit`` are fitted."""

    name: str
    fitted: tuple[str, ...]


#: The candidates, simplest first (a tie goes to the first).
SERVO_STRUCTURES: tuple[ServoStructure, ...] = (
    ServoStructure("lag", ("time_constant",)),
    ServoStructure("delay-lag", ("delay", "time_constant")),
    ServoStructure("delay-rate", ("delay", "rate_limit")),
    ServoStructure("delay-lag-rate", ("delay", "time_constant", "rate_limit")),
)


def structure_values(
    parameters: Mapping[str, ServoParameter], structure: ServoStructure, z: np.ndarray
) -> dict[str, np.ndarray]:
    """Every parameter, shape (G,), at unit coordinates ``z`` (G, fitted) of ``structure``."""
    out = {name: np.full(len(z), p.neutral) for name, p in parameters.items()}
    for i, name in enumerate(structure.fitted):
        out[name] = parameters[name].value(z[:, i])
    return out


def structure_grid(parameters: Mapping[str, ServoParameter], structure: ServoStructure) -> np.ndarray:
    """The coarse grid of ``structure`` in unit coordinates, shape (G, fitted)."""
    axes = [np.linspace(0.0, 1.0, parameters[name].grid) for name in structure.fitted]
    return np.array(list(itertools.product(*axes))).reshape(-1, len(structure.fitted))


def bound_hits(
    parameters: Mapping[str, ServoParameter], structure: ServoStructure, values: Mapping[str, float]
) -> tuple[str, ...]:
    """The fitted parameters on an implausible bound of ``parameters``, in words."""
    hits = []
    for name in structure.fitted:
        p, value = parameters[name], values[name]
        if value >= p.upper - 1e-3 * (p.upper - p.lower):
            hits.append(f"{name} at its upper bound {p.upper:g} {p.unit}")
        elif value <= p.lower + 1e-3 * (p.upper - p.lower) and not p.lower_is_a_result:
            hits.append(f"{name} at its lower bound {p.lower:g} {p.unit}")
    return tuple(hits)


def refine(
    objective: Callable[[np.ndarray], np.ndarray], z0: np.ndarray, steps: np.ndarray, rounds: int = 4
) -> tuple[np.ndarray, float]:
    """Minimise a vectorised ``objective`` near ``z0`` (unit coordinates), one grid cell ``steps`` wide.

    Each round evaluates the ``3^p`` points ``z + {-h, 0, h}`` per coordinate (kept in [0, 1]),
    moves to the best and halves ``h`` (starting at half a grid cell). Deterministic, and never
    worse than ``z0``.

    Returns
    -------
    z : numpy.ndarray
        The best point, shape (p,).
    value : float
        The objective there.
    """
    best = np.asarray(z0, dtype=float)
    value = float(objective(best[None, :])[0])
    h = 0.5 * np.asarray(steps, dtype=float)
    offsets = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=len(best))))
    for _ in range(rounds):
        points = np.unique(np.clip(best + offsets * h, 0.0, 1.0), axis=0)
        values = objective(points)
        i = int(np.argmin(values))
        if values[i] < value:
            best, value = points[i], float(values[i])
        h = h / 2.0
    return best, value


def r_squared(y: np.ndarray, fit: np.ndarray) -> float:
    """Coefficient of determination of ``fit`` for ``y`` (1 when ``y`` does not vary)."""
    ss = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - fit) ** 2)) / ss if ss > 0 else 1.0


def history_depth(dt: float) -> int:
    """Past commands a prediction needs beyond the current one: ``u_{k-1} ... u_{k-depth}``."""
    return math.floor(MAX_DELAY / dt + 1e-9) + 1


def _split_delay(delay: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Whole periods ``m`` and the remainder ``f`` (s) of a delay: ``d = m T + f``, ``0 <= f < T``."""
    whole = np.floor(delay / dt + 1e-9).astype(int)
    return whole, np.maximum(delay - whole * dt, 0.0)


def _hold(
    delta: np.ndarray, target: np.ndarray, duration: np.ndarray, tau: np.ndarray, rate: np.ndarray
) -> np.ndarray:
    """Wheel angle (rad) after ``duration`` (s) of ``d delta/dt = clip((target - delta)/tau, -rate, rate)``.

    Exact: the wheel moves at the rate limit while the error exceeds ``rate * tau``, then
    decays exponentially.
    """
    gap = target - delta
    ramp = np.clip((np.abs(gap) - rate * tau) / rate, 0.0, duration)
    moved = delta + np.sign(gap) * rate * ramp
    return target - (target - moved) * np.exp(-(duration - ramp) / tau)


def _parameter_arrays(
    delay: np.ndarray | float, time_constant: np.ndarray | float, rate_limit: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d, tau, rate = (np.atleast_1d(np.asarray(p, dtype=float)) for p in (delay, time_constant, rate_limit))
    d, tau, rate = np.broadcast_arrays(d, tau, np.minimum(rate, _UNLIMITED))
    return d, tau, rate


def servo_step(
    delta: np.ndarray,
    commands: np.ndarray,
    dt: float,
    delay: np.ndarray | float,
    time_constant: np.ndarray | float,
    rate_limit: np.ndarray | float,
) -> np.ndarray:
    """The wheel angle one period later, for one or many parameter sets.

    Parameters
    ----------
    delta : numpy.ndarray
        Wheel angle now (rad), shape (n,).
    commands : numpy.ndarray
        Steering commands ``[u_k, u_{k-1}, ..., u_{k-depth}]`` (rad), shape (n, depth + 1),
        ``depth`` at least :func:`history_depth`.
    dt : float
        Control period T (s).
    delay, time_constant, rate_limit : float or numpy.ndarray
        Delay (s), lag (s) and rate limit (rad/s; ``inf`` for none), scalars or shape (G,).

    Returns
    -------
    numpy.ndarray
        Shape (n,) for scalar parameters, else (G, n).
    """
    scalar = np.ndim(delay) == np.ndim(time_constant) == np.ndim(rate_limit) == 0
    d, tau, rate = _parameter_arrays(delay, time_constant, rate_limit)
    whole, rest = _split_delay(d, dt)
    columns = np.asarray(commands, dtype=float).T
    tau, rate, rest = tau[:, None], rate[:, None], rest[:, None]
    # The first ``rest`` seconds of the period still see the command of one period earlier.
    mid = _hold(np.asarray(delta, dtype=float)[None, :], columns[whole + 1], rest, tau, rate)
    out = _hold(mid, columns[whole], dt - rest, tau, rate)
    return out[0] if scalar else out


def simulate_servo(
    commands: np.ndarray,
    starts: np.ndarray,
    initial: np.ndarray,
    dt: float,
    delay: np.ndarray,
    time_constant: np.ndarray,
    rate_limit: np.ndarray,
) -> np.ndarray:
    """The wheel angle at the end of every period, run from the commands alone, for G parameter sets.

    Parameters
    ----------
    commands : numpy.ndarray
        ``[u_k, u_{k-1}, ..., u_{k-depth}]`` of each transition (rad), shape (N, depth + 1), finite
        (commands before an episode's start: its first command, the car at rest on it).
    starts : numpy.ndarray
        Whether each transition starts an episode, shape (N,) bool.
    initial : numpy.ndarray
        Wheel angle (rad) at the start of each transition, shape (N,); read where ``starts``.
    dt : float
        Control period (s).
    delay, time_constant, rate_limit : numpy.ndarray
        Parameter sets, shape (G,): delay (s), lag (s), rate limit (rad/s; ``inf`` for none).

    Returns
    -------
    numpy.ndarray
        Wheel angle at the end of each transition (rad), shape (G, N).
    """
    d, tau, rate = _parameter_arrays(delay, time_constant, rate_limit)
    whole, rest = _split_delay(d, dt)
    commands = np.asarray(commands, dtype=float)
    n, g = len(commands), len(d)
    out = np.empty((g, n))
    delta = np.zeros(g)
    # _hold, unrolled with what does not change from step to step computed once.
    band, inv_rate, inv_tau = rate * tau, 1.0 / rate, 1.0 / tau
    holds = [(whole + 1, rest, np.exp(-rest * inv_tau)), (whole, dt - rest, np.exp(-(dt - rest) * inv_tau))]
    for k in range(n):
        if starts[k]:
            delta = np.full(g, float(initial[k]))
        row = commands[k]
        for column, duration, decay in holds:
            target = row[column]
            gap = target - delta
            size = np.abs(gap)
            ramp = np.minimum(np.maximum(size - band, 0.0) * inv_rate, duration)
            # Moved at the rate limit for ``ramp`` seconds, then decayed exponentially.
            delta = target - np.copysign(size - rate * ramp, gap) * (decay * np.exp(ramp * inv_tau))
        out[:, k] = delta
    return out


def delay_periods(delay: float, dt: float) -> int:
    """Whole control periods ``m`` in a delay ``d = m T + f`` (s), ``0 <= f < T``."""
    return int(_split_delay(np.array([delay]), dt)[0][0])


def lag_delay_weights(time_constant: float, delay: float, dt: float) -> tuple[float, np.ndarray]:
    """Exact discretisation of a delayed first-order lag under commands held over ``dt``.

    ``delta_{k+1} = a delta_k + sum_j w_j u_{k-j}``, ``j = 0 .. len(w) - 1``.

    Parameters
    ----------
    time_constant : float
        Lag (s), > 0.
    delay : float
        Delay (s), >= 0.
    dt : float
        Control period (s).

    Returns
    -------
    a : float
        ``exp(-T / tau)``.
    w : numpy.ndarray
        Weights of ``u_k, u_{k-1}, ...``: ``1 - exp(-(T - f) / tau)`` on ``u_{k-m}`` and
        ``exp(-(T - f) / tau) - a`` on ``u_{k-m-1}`` for ``d = m T + f`` (the latter left
        out when ``f = 0``); they sum to ``1 - a``.
    """
    whole = delay_periods(delay, dt)
    rest = max(delay - whole * dt, 0.0)
    a = math.exp(-dt / time_constant)
    late = math.exp(-(dt - rest) / time_constant)
    w = np.zeros(whole + (2 if rest > 0.0 else 1))
    w[whole] = 1.0 - late
    if rest > 0.0:
        w[whole + 1] = late - a
    return a, w
