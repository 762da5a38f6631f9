"""The steering servo from on-track data: candidate structures, fitted and chosen by BIC.

A real steering actuator is rarely a clean first-order lag. Hobby servos and
road-car racks add a transport delay (bus, firmware, a slower actuator loop)
and many move at a fixed rate whatever the error. Every candidate here is one
continuous-time model,

    d delta / dt = clip((u(t - d) - delta) / tau, -R, R),

with the command ``u`` held over each control period ``T`` (zero-order hold),
a pure delay ``d`` that may be a fraction of ``T``, a lag ``tau`` and a rate
limit ``R``. A structure (:data:`SERVO_STRUCTURES`) says which of the three
are fitted; the others keep their neutral value (no delay, a lag too fast to
resolve, no rate limit). :func:`servo_step` integrates the model exactly over
one period, so the same function predicts for a fit at any delay and rate.

The fit minimises the one-step prediction error of the measured wheel angle,
``delta_{k+1} - servo_step(delta_k, u_k, u_{k-1}, ...)``: a coarse grid over
every fitted parameter (the delay makes the error multi-modal), then
Nelder-Mead from the best grid point, inside the plausible ranges of
:data:`SERVO_PARAMETERS`; a rate limit no lower than the largest wheel rate the
data show (a wheel is never slower than it was seen to move). A structure is
chosen by the Bayesian information criterion, ``BIC = n ln(max(RSS / n, NOISE_FLOOR^2)) + p ln n``, among the
structures whose parameters stay off their implausible bounds; the floor
makes fits better than any sensor could tell apart count as ties, which the
simpler structure wins. Without a rate limit the model is linear and
:func:`lag_delay_weights` gives its exact discretisation, the one ``lmpc-id``
predicts with.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize

__all__ = [
    "MAX_DELAY",
    "NOISE_FLOOR",
    "SERVO_MIN_R2",
    "SERVO_PARAMETERS",
    "SERVO_STRUCTURES",
    "ServoFit",
    "ServoParameter",
    "ServoStructure",
    "delay_periods",
    "fit_servo",
    "history_depth",
    "lag_delay_weights",
    "r_squared",
    "servo_step",
]

#: Largest plausible steering delay (s): three periods of a 20 Hz controller.
MAX_DELAY = 0.15
#: One-step residual RMS (rad) below which fits count as exact: a wheel-angle sensor's resolution.
NOISE_FLOOR = 1e-4
#: A servo fit explaining less than this share of the wheel-angle changes is not used.
SERVO_MIN_R2 = 0.5
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
        Value of a structure that does not fit it (no delay, the fastest lag, no limit).
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


#: The three parameters of every candidate, with their plausible ranges: a delay of up to
#: 0.15 s, a time constant of 5 ms (a fast digital servo) to 1 s (slower than any car's
#: steering), a wheel rate of 0.1 rad/s (slower than a road car's rack, about 0.4 rad/s at
#: the wheel) to 20 rad/s (faster than any servo the data at 20 Hz could show).
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


@dataclass(frozen=True)
class ServoStructure:
    """A candidate servo: which of ``delay``, ``time_constant``, ``rate_limit`` are fitted."""

    name: str
    fitted: tuple[str, ...]


#: The candidates, simplest first (a tie in BIC goes to the first).
SERVO_STRUCTURES: tuple[ServoStructure, ...] = (
    ServoStructure("lag", ("time_constant",)),
    ServoStructure("delay-lag", ("delay", "time_constant")),
    ServoStructure("delay-rate", ("delay", "rate_limit")),
    ServoStructure("delay-lag-rate", ("delay", "time_constant", "rate_limit")),
)


@dataclass(frozen=True)
class ServoFit:
    """The best fit of one structure.

    Parameters
    ----------
    structure : str
        Name in :data:`SERVO_STRUCTURES`.
    time_constant, delay : float
        Lag (s) and delay (s).
    rate_limit : float or None
        Wheel rate limit (rad/s), None when the structure has none.
    r2 : float
        Share of the variance of the one-step wheel-angle changes the fit explains.
    bic : float
        Bayesian information criterion (lower is better).
    at_bound : tuple of str
        Parameters that ended on an implausible bound, in words (empty when none).
    """

    structure: str
    time_constant: float
    delay: float
    rate_limit: float | None
    r2: float
    bic: float
    at_bound: tuple[str, ...]


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
    d, tau, rate = (np.atleast_1d(np.asarray(p, dtype=float)) for p in (delay, time_constant, rate_limit))
    d, tau, rate = np.broadcast_arrays(d, tau, np.minimum(rate, _UNLIMITED))
    whole, rest = _split_delay(d, dt)
    columns = np.asarray(commands, dtype=float).T
    tau, rate, rest = tau[:, None], rate[:, None], rest[:, None]
    # The first ``rest`` seconds of the period still see the command of one period earlier.
    mid = _hold(np.asarray(delta, dtype=float)[None, :], columns[whole + 1], rest, tau, rate)
    out = _hold(mid, columns[whole], dt - rest, tau, rate)
    return out[0] if scalar else out


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


class _Problem:
    """One-step prediction error of the data for parameter sets in unit coordinates.

    The wheel cannot be slower than the data show: the rate limit is searched from the
    largest wheel rate observed, ``max |delta_{k+1} - delta_k| / T``, up.
    """

    def __init__(self, delta: np.ndarray, delta_next: np.ndarray, commands: np.ndarray, dt: float) -> None:
        self.delta, self.delta_next, self.commands, self.dt = delta, delta_next, commands, dt
        rate = SERVO_PARAMETERS["rate_limit"]
        observed = float(np.max(np.abs(delta_next - delta))) / dt
        lower = min(max(rate.lower, observed), rate.upper)
        self.parameters = {**SERVO_PARAMETERS, "rate_limit": replace(rate, lower=lower)}

    def values(self, structure: ServoStructure, z: np.ndarray) -> dict[str, np.ndarray]:
        """Every parameter, shape (G,), at unit coordinates ``z`` (G, fitted) of ``structure``."""
        out = {name: np.full(len(z), p.neutral) for name, p in self.parameters.items()}
        for i, name in enumerate(structure.fitted):
            out[name] = self.parameters[name].value(z[:, i])
        return out

    def rss(self, structure: ServoStructure, z: np.ndarray, chunk: int = 256) -> np.ndarray:
        """Residual sum of squares (rad^2) of each row of ``z``, shape (G,)."""
        out = np.empty(len(z))
        for start in range(0, len(z), chunk):
            v = self.values(structure, z[start : start + chunk])
            pred = servo_step(
                self.delta, self.commands, self.dt, v["delay"], v["time_constant"], v["rate_limit"]
            )
            out[start : start + chunk] = np.sum((self.delta_next - pred) ** 2, axis=1)
        return out


def _fit_one(problem: _Problem, structure: ServoStructure, ss_total: float) -> tuple[np.ndarray, float]:
    """Unit coordinates and RSS of the best fit of ``structure``: coarse grid, then Nelder-Mead."""
    params = [problem.parameters[name] for name in structure.fitted]
    grid = np.array(list(itertools.product(*(np.linspace(0.0, 1.0, p.grid) for p in params))))
    rss = problem.rss(structure, grid)
    z0 = grid[int(np.argmin(rss))]
    # The first simplex spans one grid cell from the best point, inwards at the bounds.
    steps = np.array([1.0 / (p.grid - 1) for p in params])
    simplex = [z0]
    for i, step in enumerate(steps):
        vertex = z0.copy()
        vertex[i] += step if z0[i] + step <= 1.0 else -step
        simplex.append(vertex)
    result = minimize(
        lambda z: float(problem.rss(structure, z[None, :])[0]),
        z0,
        method="Nelder-Mead",
        bounds=[(0.0, 1.0)] * len(params),
        options={
            "initial_simplex": np.array(simplex),
            "xatol": 1e-4,
            "fatol": 1e-9 * ss_total,
            "maxfev": 150 * len(params),
        },
    )
    best = np.clip(result.x, 0.0, 1.0)
    best_rss = float(problem.rss(structure, best[None, :])[0])
    if best_rss > float(rss.min()):  # never worse than the grid
        best, best_rss = z0, float(rss.min())
    return best, best_rss


def _bound_hits(structure: ServoStructure, values: dict[str, float]) -> tuple[str, ...]:
    """The fitted parameters on an implausible bound of :data:`SERVO_PARAMETERS`, in words."""
    hits = []
    for name in structure.fitted:
        p, value = SERVO_PARAMETERS[name], values[name]
        if value >= p.upper - 1e-3 * (p.upper - p.lower):
            hits.append(f"{name} at its upper bound {p.upper:g} {p.unit}")
        elif value <= p.lower + 1e-3 * (p.upper - p.lower) and not p.lower_is_a_result:
            hits.append(f"{name} at its lower bound {p.lower:g} {p.unit}")
    return tuple(hits)


def fit_servo(
    delta: np.ndarray, delta_next: np.ndarray, commands: np.ndarray, dt: float
) -> tuple[ServoFit, ...]:
    """Fit every structure of :data:`SERVO_STRUCTURES`; best (lowest BIC) first.

    Parameters
    ----------
    delta, delta_next : numpy.ndarray
        Measured wheel angle at the start and the end of each period (rad), shape (n,).
    commands : numpy.ndarray
        Steering commands ``[u_k, u_{k-1}, ..., u_{k-depth}]`` (rad), shape (n, depth + 1),
        ``depth = history_depth(dt)``; finite.
    dt : float
        Control period T (s).

    Returns
    -------
    tuple of ServoFit
        One per structure, sorted by BIC (ties keep the order of :data:`SERVO_STRUCTURES`).
    """
    n = len(delta)
    change = delta_next - delta
    ss_total = float(np.sum((change - change.mean()) ** 2))
    problem = _Problem(delta, delta_next, commands, dt)
    fits = []
    for structure in SERVO_STRUCTURES:
        z, rss = _fit_one(problem, structure, ss_total)
        v = {name: float(a[0]) for name, a in problem.values(structure, z[None, :]).items()}
        bic = n * math.log(max(rss / n, NOISE_FLOOR**2)) + len(structure.fitted) * math.log(n)
        fits.append(
            ServoFit(
                structure=structure.name,
                time_constant=v["time_constant"],
                delay=v["delay"],
                rate_limit=v["rate_limit"] if "rate_limit" in structure.fitted else None,
                r2=1.0 - rss / ss_total if ss_total > 0 else 1.0,
                bic=bic,
                at_bound=_bound_hits(structure, v),
            )
        )
    return tuple(sorted(fits, key=lambda f: f.bic))
