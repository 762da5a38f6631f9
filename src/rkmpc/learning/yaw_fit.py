"""The servo and the understeer gradient from the response of the yaw rate to the commands.

A car without a steering-angle sensor still shows how its wheel moved: the yaw
rate follows ``r = v tan(delta) / (L + K v^2)``
(:func:`~rkmpc.learning.understeer.yaw_rate_of`). For a candidate servo, the
wheel angle ``delta`` is run from the commands alone
(:func:`~rkmpc.learning.servo_model.simulate_servo`, from the first command of
each episode), and ``K`` is the least-squares gradient of that wheel
(:func:`~rkmpc.learning.understeer.fit_gradients`). Every structure of
:data:`~rkmpc.learning.servo_model.SERVO_STRUCTURES`, with ``K`` fitted or held
at 0, is a candidate, and so are the car's nominal servo with and without ``K``;
each is fitted on a coarse grid of its parameters (the error is multi-modal in
the delay) for every block of the cross-validation at once, and scored on the
block it did not see (:mod:`rkmpc.learning.heldout`). The one kept is refined
on all the data (:func:`~rkmpc.learning.servo_model.refine`).

What this identifies is the steering as the yaw rate sees it: the servo and the
chassis's own lag in building up yaw together, which is the wheel a kinematic
model (``lmpc-id``'s) must be given to turn like the car.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rkmpc.learning.heldout import Folds, Score
from rkmpc.learning.servo_model import (
    SERVO_STRUCTURES,
    ServoParameter,
    ServoStructure,
    simulate_servo,
    structure_grid,
    structure_values,
)
from rkmpc.learning.understeer import fit_gradients, yaw_rate_of

__all__ = ["Candidate", "ServoInput", "YawTarget", "yaw_candidates"]

#: Floats of one (parameter sets x fits x samples) block of the evaluation (memory bound).
_BLOCK_FLOATS = 2_000_000
#: Floats of one (parameter sets x samples) simulation (memory bound; the simulation loops over time
#: in Python, so the more sets at once the better).
_SIMULATION_FLOATS = 8_000_000
#: Rounds of refinement around each fit's best grid point (the last at 1/8 of a grid cell).
_REFINE_ROUNDS = 3


@dataclass(frozen=True)
class ServoInput:
    """What drives the servo: the commands of every transition and where episodes start.

    Parameters
    ----------
    commands : numpy.ndarray
        ``[u_k, u_{k-1}, ..., u_{k-depth}]`` (rad), shape (N, depth + 1), finite (before an
        episode's start, its first command).
    starts : numpy.ndarray
        Whether each transition starts an episode, shape (N,) bool.
    initial : numpy.ndarray
        Wheel angle (rad) at the start of each transition, read where ``starts``.
    dt : float
        Control period (s).
    """

    commands: np.ndarray
    starts: np.ndarray
    initial: np.ndarray
    dt: float

    def wheel(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Wheel angle (rad) at the end of each transition for each parameter set, shape (G, N)."""
        return simulate_servo(
            self.commands,
            self.starts,
            self.initial,
            self.dt,
            values["delay"],
            values["time_constant"],
            values["rate_limit"],
        )


@dataclass(frozen=True)
class YawTarget:
    """The car's speed (m/s) and yaw rate (rad/s) at the end of each transition, shape (N,) each.

    Both are finite everywhere (0 where not usable: the sample masks leave those out).
    """

    speed: np.ndarray
    yaw_rate: np.ndarray
    wheelbase: float
    gradient_bounds: tuple[float, float]

    def squared_errors(
        self, wheel: np.ndarray, train: np.ndarray, test: np.ndarray, fit_gradient: bool
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Yaw-rate errors of G wheel histories ``wheel`` (G, N), K fitted under each row of ``train``.

        Returns the squared errors summed over each ``train`` row (G, F'), over each ``test`` row
        with the K of the ``train`` row of the same index (G, F), and K (G, F'). Samples outside
        every row may hold anything finite.
        """
        tan_wheel = np.tan(wheel)
        weights = train.astype(float)
        if not fit_gradient:
            error = (self.yaw_rate - tan_wheel * (self.speed / self.wheelbase)) ** 2
            return error @ weights.T, error @ test.T.astype(float), np.zeros((len(wheel), len(train)))
        k = fit_gradients(tan_wheel, self.speed, self.yaw_rate, weights, self.wheelbase, self.gradient_bounds)
        # yaw_rate_of, with what does not depend on K computed once.
        reach = (tan_wheel * self.speed)[:, None, :]
        error = (self.yaw_rate - reach / (self.wheelbase + k[:, :, None] * (self.speed * self.speed))) ** 2
        train_sse = np.einsum("gfn,fn->gf", error, weights)
        test_sse = np.einsum("gfn,fn->gf", error[:, : len(test)], test.astype(float))
        return train_sse, test_sse, k

    def heldout_sse(self, wheel: np.ndarray, gradients: np.ndarray, test: np.ndarray) -> np.ndarray:
        """Squared yaw-rate error of wheel history ``f`` (F, N) with ``K_f`` (F,), summed on ``test[f]``."""
        pred = yaw_rate_of(np.tan(wheel), self.speed, self.wheelbase, np.asarray(gradients)[:, None])
        return np.einsum("fn,fn->f", (self.yaw_rate - pred) ** 2, test.astype(float))


@dataclass(frozen=True)
class Candidate:
    """A candidate's held-out score and its fit on all the data.

    Parameters
    ----------
    score : Score
        Held-out yaw-rate error.
    structure : ServoStructure or None
        The servo structure; None for the car's nominal servo.
    fit_gradient : bool
        Whether K is fitted (else 0).
    final : numpy.ndarray
        Unit coordinates of the fit on all the data (empty for the nominal servo).
    """

    score: Score
    structure: ServoStructure | None
    fit_gradient: bool
    final: np.ndarray

    def fit(
        self,
        servo: ServoInput,
        yaw: YawTarget,
        usable: np.ndarray,
        parameters: Mapping[str, ServoParameter],
        nominal: Mapping[str, float],
    ) -> tuple[dict[str, float], float, np.ndarray]:
        """The fit on all ``usable`` samples: servo parameters, K (s^2/m), predicted yaw rate (rad/s)."""
        if self.structure is None:
            values = {name: np.array([value]) for name, value in nominal.items()}
        else:
            values = structure_values(parameters, self.structure, self.final[None, :])
        wheel = servo.wheel(values)
        train, test = usable[None, :], np.zeros((0, len(usable)), dtype=bool)
        k = float(yaw.squared_errors(wheel, train, test, self.fit_gradient)[2][0, 0])
        pred = yaw_rate_of(np.tan(wheel[0]), yaw.speed, yaw.wheelbase, k)
        return {name: float(v[0]) for name, v in values.items()}, k, pred


@dataclass
class _Fits:
    """The F + 1 fits of one candidate (one per held-out block, the last on all the data)."""

    structure: ServoStructure
    fit_gradient: bool
    z: np.ndarray  # unit coordinates of each fit, (F + 1, fitted)
    sse: np.ndarray  # training error of each, (F + 1,)


#: A batch of parameter sets and the K options to score them with.
_Group = tuple[Mapping[str, np.ndarray], tuple[bool, ...]]


def _evaluate(
    servo: ServoInput, yaw: YawTarget, folds: Folds, groups: Sequence[_Group]
) -> list[dict[bool, tuple[np.ndarray, np.ndarray]]]:
    """Training and held-out squared errors of every set of every group under each of its K options.

    All the groups are simulated together (the loop over time is paid once per chunk of sets).
    Per group and option: shapes (G, F + 1) and (G, F), K fitted (or 0) under each training row.
    """
    names = tuple(groups[0][0])
    values = {k: np.concatenate([np.asarray(v[k], dtype=float) for v, _ in groups]) for k in names}
    ends = np.cumsum([len(v["delay"]) for v, _ in groups])
    starts = ends - np.diff(np.concatenate([[0], ends]))
    n, fits = folds.train.shape[1], folds.train.shape[0]
    chunk, sub = max(1, _SIMULATION_FLOATS // n), max(1, _BLOCK_FLOATS // (n * fits))
    parts: list[dict[bool, tuple[list[np.ndarray], list[np.ndarray]]]] = [
        {o: ([], []) for o in options} for _, options in groups
    ]
    for s in range(0, int(ends[-1]), chunk):
        wheel = servo.wheel({k: v[s : s + chunk] for k, v in values.items()})
        for g, (lo, hi) in enumerate(zip(starts, ends, strict=True)):
            for t in range(max(lo, s), min(hi, s + chunk), sub):
                w = wheel[t - s : min(hi, s + chunk, t + sub) - s]
                for option, (train_parts, test_parts) in parts[g].items():
                    train_sse, test_sse, _ = yaw.squared_errors(w, folds.train, folds.test, option)
                    train_parts.append(train_sse)
                    test_parts.append(test_sse)
    return [{o: (np.concatenate(tr), np.concatenate(te)) for o, (tr, te) in p.items()} for p in parts]


def _cell(parameters: Mapping[str, ServoParameter], structure: ServoStructure) -> np.ndarray:
    """One grid cell of ``structure`` in unit coordinates, per fitted parameter."""
    return np.array([1.0 / (parameters[name].grid - 1) for name in structure.fitted])


def _zoom(
    servo: ServoInput,
    yaw: YawTarget,
    folds: Folds,
    parameters: Mapping[str, ServoParameter],
    fits: Sequence[_Fits],
    step: float,
) -> None:
    """One round of :func:`~rkmpc.learning.servo_model.refine` for every fit of every candidate at once.

    Fit ``f`` of a candidate tries ``z_f + {-h, 0, h}`` per coordinate, ``h`` = ``step`` grid cells,
    scored on its own training samples, and moves to the best.
    """
    folds_n = folds.count + 1
    groups, points = [], []
    for fit in fits:
        offsets = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=len(fit.structure.fitted))))
        p = np.clip(fit.z[:, None, :] + offsets * step * _cell(parameters, fit.structure), 0.0, 1.0)
        points.append(p)
        groups.append(
            (structure_values(parameters, fit.structure, p.reshape(-1, p.shape[2])), (fit.fit_gradient,))
        )
    for fit, p, result in zip(fits, points, _evaluate(servo, yaw, folds, groups), strict=True):
        train = result[fit.fit_gradient][0].reshape(folds_n, p.shape[1], folds_n)
        own = train[np.arange(folds_n), :, np.arange(folds_n)]  # fit f on its own samples, (F + 1, M)
        best = np.argmin(own, axis=1)
        value = own[np.arange(folds_n), best]
        better = value < fit.sse
        fit.z[better] = p[better, best[better]]
        fit.sse[better] = value[better]


def _name(structure: ServoStructure | None, fit_gradient: bool) -> str:
    return ("nominal" if structure is None else structure.name) + (" + K" if fit_gradient else "")


def yaw_candidates(
    servo: ServoInput,
    yaw: YawTarget,
    folds: Folds,
    parameters: Mapping[str, ServoParameter],
    nominal: Mapping[str, float],
    *,
    servo_structures: tuple[ServoStructure, ...] = SERVO_STRUCTURES,
) -> list[Candidate]:
    """Every candidate scored on the held-out blocks of ``folds``: the nominal servo first, K = 0 first.

    Each candidate is fitted once per block (on the other blocks) and once on all the data: the
    best point of a coarse grid, refined in :data:`_REFINE_ROUNDS` rounds.

    Parameters
    ----------
    servo : ServoInput
        The commands.
    yaw : YawTarget
        Speed and yaw rate to predict.
    folds : Folds
        Blocks, restricted to the samples with a usable yaw rate.
    parameters : mapping of str to ServoParameter
        The plausible servo (:func:`~rkmpc.learning.servo_model.vehicle_servo_parameters`).
    nominal : mapping of str to float
        The car's nominal servo: ``delay``, ``time_constant``, ``rate_limit``.
    servo_structures : tuple of ServoStructure
        The structures fitted (none when the commands do not excite the servo).
    """
    count = folds.test.sum(axis=1)
    folds_n = folds.count + 1
    options = (False, True)
    fixed = {name: np.array([value]) for name, value in nominal.items()}
    grids = [structure_grid(parameters, s) for s in servo_structures]
    groups: list[_Group] = [(fixed, options)]
    groups += [
        (structure_values(parameters, s, g), options) for s, g in zip(servo_structures, grids, strict=True)
    ]
    results = _evaluate(servo, yaw, folds, groups)
    candidates = [
        Candidate(Score(_name(None, o), int(o), results[0][o][1][0], count), None, o, np.zeros(0))
        for o in options
    ]
    fits = []
    for structure, grid, result in zip(servo_structures, grids, results[1:], strict=True):
        for o in options:
            train = result[o][0]
            best = np.argmin(train, axis=0)  # per fit: the grid point it starts from
            fits.append(_Fits(structure, o, grid[best].copy(), train[best, np.arange(folds_n)].copy()))
    if fits:
        for r in range(_REFINE_ROUNDS):
            _zoom(servo, yaw, folds, parameters, fits, 0.5 ** (r + 1))
        # Each fit predicts its own held-out block.
        held = [(structure_values(parameters, f.structure, f.z[:-1]), (f.fit_gradient,)) for f in fits]
        for fit, result in zip(fits, _evaluate(servo, yaw, folds, held), strict=True):
            sse = result[fit.fit_gradient][1][np.arange(folds.count), np.arange(folds.count)]
            fitted = len(fit.structure.fitted) + int(fit.fit_gradient)
            nonlinear = "rate_limit" in fit.structure.fitted
            score = Score(_name(fit.structure, fit.fit_gradient), fitted, sse, count, nonlinear)
            candidates.append(Candidate(score, fit.structure, fit.fit_gradient, fit.z[-1]))
    return candidates
