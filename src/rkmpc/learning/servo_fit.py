"""The steering servo fitted to a measured wheel angle: one-step prediction, every structure.

The direct fit, for data with a wheel-angle sensor. Each structure of
:data:`~rkmpc.learning.servo_model.SERVO_STRUCTURES` is fitted to the one-step
prediction error of the measured wheel angle,
``delta_{k+1} - servo_step(delta_k, u_k, u_{k-1}, ...)``: a coarse grid over
every fitted parameter (the delay makes the error multi-modal), then
:func:`~rkmpc.learning.servo_model.refine` from the best grid point, inside the
plausible ranges of a parameter space (:data:`~rkmpc.learning.servo_model.SERVO_PARAMETERS`
or :func:`~rkmpc.learning.servo_model.vehicle_servo_parameters`); a rate limit
no lower than the largest wheel rate the data show (a wheel is never slower
than it was seen to move). :func:`fit_servo` ranks the structures by the
Bayesian information criterion,
``BIC = n ln(max(RSS / n, NOISE_FLOOR^2)) + p ln n``: an in-sample figure.
Identification (:func:`rkmpc.learning.identification.identify`) chooses a
structure by held-out prediction instead and uses this fit for the parameters
of the one it chose.

The servo's model itself lives in :mod:`rkmpc.learning.servo_model`; its names are
re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from rkmpc.learning.heldout import Folds, Score
from rkmpc.learning.servo_model import (
    MAX_DELAY,
    SERVO_PARAMETERS,
    SERVO_STRUCTURES,
    ServoParameter,
    ServoStructure,
    bound_hits,
    delay_periods,
    history_depth,
    lag_delay_weights,
    r_squared,
    refine,
    servo_step,
    structure_grid,
    structure_values,
)

__all__ = [
    "MAX_DELAY",
    "NOISE_FLOOR",
    "SERVO_MIN_R2",
    "SERVO_PARAMETERS",
    "SERVO_STRUCTURES",
    "OneStepProblem",
    "ServoFit",
    "ServoParameter",
    "ServoStructure",
    "delay_periods",
    "fit_servo",
    "heldout_servo_scores",
    "history_depth",
    "lag_delay_weights",
    "r_squared",
    "servo_step",
]

#: One-step residual RMS (rad) below which fits count as exact: a wheel-angle sensor's resolution.
NOISE_FLOOR = 1e-4
#: A servo fit explaining less than this share of the wheel-angle changes explains little (in sample).
SERVO_MIN_R2 = 0.5


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
        Wheel rate limit (rad/s), None when the structure does not fit one.
    r2 : float
        Share of the variance of the one-step wheel-angle changes the fit explains (in sample).
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


class OneStepProblem:
    """One-step prediction error of a measured wheel angle, for parameter sets in unit coordinates.

    The wheel cannot be slower than the data show: the rate limit is searched from the
    largest wheel rate observed, ``max |delta_{k+1} - delta_k| / T``, up.

    Parameters
    ----------
    delta, delta_next : numpy.ndarray
        Measured wheel angle at the start and the end of each period (rad), shape (n,), finite.
    commands : numpy.ndarray
        ``[u_k, u_{k-1}, ..., u_{k-depth}]`` (rad), shape (n, depth + 1), finite.
    dt : float
        Control period (s).
    parameters : mapping of str to ServoParameter
        The parameter space searched.
    """

    def __init__(
        self,
        delta: np.ndarray,
        delta_next: np.ndarray,
        commands: np.ndarray,
        dt: float,
        parameters: Mapping[str, ServoParameter] = SERVO_PARAMETERS,
    ) -> None:
        self.delta, self.delta_next, self.commands, self.dt = delta, delta_next, commands, dt
        rate = parameters["rate_limit"]
        observed = float(np.max(np.abs(delta_next - delta))) / dt if len(delta) else 0.0
        lower = min(max(rate.lower, observed), rate.upper)
        self.parameters = {**parameters, "rate_limit": replace(rate, lower=lower)}

    def values(self, structure: ServoStructure, z: np.ndarray) -> dict[str, np.ndarray]:
        """Every parameter, shape (G,), at unit coordinates ``z`` (G, fitted) of ``structure``."""
        return structure_values(self.parameters, structure, z)

    def squared_errors(self, structure: ServoStructure, z: np.ndarray) -> np.ndarray:
        """Squared one-step errors (rad^2) of each row of ``z`` on each sample, shape (G, n)."""
        v = self.values(structure, z)
        pred = servo_step(self.delta, self.commands, self.dt, v["delay"], v["time_constant"], v["rate_limit"])
        return (self.delta_next - pred) ** 2

    def weighted_rss(self, structure: ServoStructure, weights: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Residual sum of squares (rad^2) of each row of ``z`` with sample ``weights`` (n,), shape (G,)."""
        return self.squared_errors(structure, z) @ weights

    def rss(self, structure: ServoStructure, z: np.ndarray, chunk: int = 256) -> np.ndarray:
        """Residual sum of squares (rad^2) of each row of ``z``, shape (G,)."""
        return np.concatenate(
            [self.squared_errors(structure, z[s : s + chunk]).sum(axis=1) for s in range(0, len(z), chunk)]
        )


def fit_servo(
    delta: np.ndarray,
    delta_next: np.ndarray,
    commands: np.ndarray,
    dt: float,
    *,
    parameters: Mapping[str, ServoParameter] = SERVO_PARAMETERS,
    structures: tuple[ServoStructure, ...] = SERVO_STRUCTURES,
) -> tuple[ServoFit, ...]:
    """Fit every structure of ``structures`` to the one-step wheel-angle changes; best (lowest BIC) first.

    Parameters
    ----------
    delta, delta_next : numpy.ndarray
        Measured wheel angle at the start and the end of each period (rad), shape (n,).
    commands : numpy.ndarray
        Steering commands ``[u_k, u_{k-1}, ..., u_{k-depth}]`` (rad), shape (n, depth + 1),
        ``depth = history_depth(dt)``; finite.
    dt : float
        Control period T (s).
    parameters : mapping of str to ServoParameter
        Plausible ranges searched (absolute by default; identification passes the car's,
        :func:`~rkmpc.learning.servo_model.vehicle_servo_parameters`).
    structures : tuple of ServoStructure
        The structures fitted.

    Returns
    -------
    tuple of ServoFit
        One per structure, sorted by BIC (ties keep the order of ``structures``).
    """
    n = len(delta)
    change = delta_next - delta
    ss_total = float(np.sum((change - change.mean()) ** 2))
    problem = OneStepProblem(delta, delta_next, commands, dt, parameters)
    fits = []
    for structure in structures:
        grid = structure_grid(problem.parameters, structure)
        rss = problem.rss(structure, grid)
        steps = np.array([1.0 / (problem.parameters[p].grid - 1) for p in structure.fitted])
        z, best = refine(partial(problem.rss, structure), grid[int(np.argmin(rss))], steps)
        v = {name: float(a[0]) for name, a in problem.values(structure, z[None, :]).items()}
        bic = n * math.log(max(best / n, NOISE_FLOOR**2)) + len(structure.fitted) * math.log(n)
        fits.append(
            ServoFit(
                structure=structure.name,
                time_constant=v["time_constant"],
                delay=v["delay"],
                rate_limit=v["rate_limit"] if "rate_limit" in structure.fitted else None,
                r2=1.0 - best / ss_total if ss_total > 0 else 1.0,
                bic=bic,
                at_bound=bound_hits(parameters, structure, v),
            )
        )
    return tuple(sorted(fits, key=lambda f: f.bic))


def heldout_servo_scores(
    problem: OneStepProblem,
    rows: np.ndarray,
    folds: Folds,
    simulate: Callable[[Mapping[str, np.ndarray]], np.ndarray],
    target: np.ndarray,
    structures: tuple[ServoStructure, ...] = SERVO_STRUCTURES,
) -> list[tuple[ServoStructure, Score, dict[str, np.ndarray]]]:
    """Each structure fitted one step ahead on the training blocks, scored on the held-out ones.

    Scored on the wheel angle run from the commands alone (:func:`simulate`), as a controller
    predicts it over its horizon.

    Each fit is the best point of the structure's grid, refined
    (:func:`~rkmpc.learning.servo_model.refine`), as in :func:`fit_servo`.

    Parameters
    ----------
    problem : OneStepProblem
        The one-step problem on the transitions ``rows`` (those with a measured wheel angle).
    rows : numpy.ndarray
        Indices (into the data set) of the problem's transitions, shape (n,).
    folds : Folds
        Blocks over the data set's N transitions (restricted to ``rows``).
    simulate : callable
        Parameter sets (arrays of shape (G,)) to the wheel angle at the end of every transition,
        run from the commands alone, shape (G, N).
    target : numpy.ndarray
        The measured wheel angle at the end of every transition (rad), shape (N,).
    structures : tuple of ServoStructure
        The structures fitted.

    Returns
    -------
    list of (ServoStructure, Score, dict)
        Per structure: its held-out score (wheel angle, rad) and the parameters of each fit,
        shape (F + 1,) each (the last: the fit on every row, the start of the final fit).
    """
    train = folds.train[:, rows].astype(float)
    count = folds.test.sum(axis=1)
    out = []
    for structure in structures:
        grid = structure_grid(problem.parameters, structure)
        rss = np.concatenate(
            [problem.squared_errors(structure, grid[s : s + 256]) @ train.T for s in range(0, len(grid), 256)]
        )
        cell = np.array([1.0 / (problem.parameters[p].grid - 1) for p in structure.fitted])
        z = np.array(
            [
                refine(partial(problem.weighted_rss, structure, w), grid[i], cell)[0]
                for i, w in zip(np.argmin(rss, axis=0), train, strict=True)
            ]
        )
        values = problem.values(structure, z)
        error = np.nan_to_num((target - simulate(values)[: folds.count]) ** 2)
        sse = np.einsum("fn,fn->f", error, folds.test)
        nonlinear = "rate_limit" in structure.fitted
        out.append((structure, Score(structure.name, len(structure.fitted), sse, count, nonlinear), values))
    return out
