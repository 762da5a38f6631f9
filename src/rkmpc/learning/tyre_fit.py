"""Tyres from laps: the lateral force curves of both axles, the structure chosen on held-out blocks.

What the data allow
-------------------
With the side slip measured (a simulator; a real car with an optical ground-speed sensor),
each transition's yaw rate and lateral velocity one period later follow from its measured start
and the two axle forces (:mod:`rkmpc.learning.tyre_dynamics`): both curves are identifiable as
far as the slip angles of the data reach. Without it (a real F1TENTH car measures the yaw rate,
the speed and its commands), only the yaw rate's response to the wheel angle is seen: its steady
state fixes the understeer gradient ``K = (1 / c_f - 1 / c_r) / g`` (the *ratio* of the
stiffnesses per unit load), their *scale* shows only in the transient, whose time constants on a
1:10 car are a few tens of milliseconds, about one control period. Runs of :data:`RUN_PERIODS`
periods are then predicted from a kinematic start and scored after :data:`BURN_IN` periods,
and the held-out choice says whether the scale is seen; no curvature is fitted.

Candidates
----------
Curves per unit vertical load, friction included, on the car's nominal chassis (mass, inertia,
axle distances, height of the centre of gravity):

* ``nominal`` (0 parameters): the car's nominal tyres;
* ``grip`` (2): each axle's nominal curve scaled (a friction or tyre-wear change);
* ``ratio`` (1, without side slip only): linear curves of the nominal stiffnesses' geometric
  mean and a fitted ratio, the understeer gradient alone; the only candidate when the wheel angle
  is run through a servo fitted on the yaw rate, which already holds the chassis's lag (the
  scale's effect) and so leaves the scale unidentifiable. Every candidate (the nominal tyres
  too) is then also fitted with the wheel run through that servo's lag without its delay and
  through the car's nominal servo, and held-out data choose the servo with the tyres;
* ``linear`` (2): ``Fy / Fz = c alpha`` per axle;
* ``pacejka`` (4, with side slip only): the simplified magic formula ``D sin(C atan(B alpha))``
  with the stiffness ``B C D`` and the peak factor ``D`` fitted per axle and ``C`` held at the
  car's nominal shape factor: below the peak, data determine a curve's slope and curvature, not
  a third shape parameter as well.

Each is fitted by least squares (:func:`scipy.optimize.least_squares`, evaluations capped) on
all but one time block and scores the block it did not see; a signal's squared error is divided
by the variance of its one-step change (a score of 1 is the error of predicting no change).
:func:`~rkmpc.learning.heldout.choose` keeps the nominal tyres unless a candidate beats them by
the margin, a more complex one must beat the simpler ones as much, and a final fit with a
parameter on its bound is dropped (with a warning) and the choice made again.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.heldout import DEFAULT_FOLDS, GAP_SECONDS, Folds, Score, choose, time_blocks
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.tyre_data import (
    TyreData,
    confounded,
    limits,
    prepare,
    reach_notes,
    steady_start,
    unexcited,
)
from rkmpc.learning.tyre_dynamics import Chassis, Runs, predict
from rkmpc.learning.tyre_model import MAX_PEAK_FACTOR, AxleCurve, IdentifiedTyres, nominal_curves
from rkmpc.vehicle.params import VehicleParams

__all__ = ["MAX_EVALUATIONS", "identify_tyres"]

#: Model evaluations of one least-squares fit at most (an iteration cap: no wall-clock budget).
MAX_EVALUATIONS = 200


@dataclass(frozen=True)
class _Structure:
    """A candidate: its parameters (logarithms), their bounds and start, and the curves they give."""

    name: str
    start: np.ndarray
    low: np.ndarray
    high: np.ndarray
    curves: Callable[[np.ndarray], tuple[AxleCurve, AxleCurve]]
    nonlinear: bool


def _structures(nominal: tuple[AxleCurve, AxleCurve], slip: bool, scale: bool) -> list[_Structure]:
    """The candidates: with side slip, grip, linear and Pacejka; without, grip, ratio and linear, or the
    ratio alone when the scale of the stiffnesses cannot be told from the servo (``scale`` False)."""
    front, rear = nominal
    k = np.log([front.stiffness, rear.stiffness])
    d = np.log([front.parameters[2], rear.parameters[2]])
    shape = (front.parameters[1], rear.parameters[1])
    log = np.log

    def grip(t: np.ndarray) -> tuple[AxleCurve, AxleCurve]:
        scaled = [
            AxleCurve.pacejka(
                c.parameters[0], c.parameters[1], c.parameters[2] * math.exp(s), c.parameters[3]
            )
            for c, s in zip(nominal, t, strict=True)
        ]
        return scaled[0], scaled[1]

    def ratio(t: np.ndarray) -> tuple[AxleCurve, AxleCurve]:
        mean = math.exp(0.5 * (k[0] + k[1]))
        return AxleCurve.linear(mean * math.exp(t[0])), AxleCurve.linear(mean * math.exp(-t[0]))

    def linear(t: np.ndarray) -> tuple[AxleCurve, AxleCurve]:
        return AxleCurve.linear(math.exp(t[0])), AxleCurve.linear(math.exp(t[1]))

    def pacejka(t: np.ndarray) -> tuple[AxleCurve, AxleCurve]:
        out = []
        for c, stiffness, peak in zip(shape, np.exp(t[0::2]), np.exp(t[1::2]), strict=True):
            out.append(AxleCurve.pacejka(stiffness / (c * peak), c, peak))
        return out[0], out[1]

    top = math.log(MAX_PEAK_FACTOR) - 1e-6  # the largest peak factor a curve may have, rounding kept inside
    grip_s = _Structure("grip", np.zeros(2), log([0.1, 0.1]), np.minimum(log(3.0), top - d), grip, True)
    ratio_s = _Structure("ratio", np.array([0.5 * (k[0] - k[1])]), log([0.1]), log([10.0]), ratio, False)
    linear_s = _Structure("linear", k.copy(), log([0.2, 0.2]), log([50.0, 50.0]), linear, False)
    start = np.array([k[0], d[0], k[1], d[1]])
    high = np.array([log(50.0), top] * 2)
    pacejka_s = _Structure("pacejka", start, log([0.2, 0.05] * 2), high, pacejka, True)
    if slip:
        return [grip_s, linear_s, pacejka_s]
    return [grip_s, ratio_s, linear_s] if scale else [ratio_s]


def _residuals(d: TyreData, runs: Runs, curves: tuple[AxleCurve, AxleCurve], chassis: Chassis) -> np.ndarray:
    """Scaled prediction errors of the scored boundaries: yaw rate, then lateral velocity (side slip)."""
    runs = steady_start(d, runs, curves[1], chassis)
    beta, r = predict(runs, chassis, curves[0].force_per_load, curves[1].force_per_load)
    parts = [((r - runs.yaw_rate) / d.scales[0])[runs.scored]]
    if d.slip:
        parts.append(((runs.speed * np.sin(beta) - runs.lateral) / d.scales[1])[runs.scored])
    return np.concatenate(parts)


def _fit(s: _Structure, d: TyreData, rows: np.ndarray, chassis: Chassis, start: np.ndarray) -> np.ndarray:
    runs = d.runs.subset(rows)
    result = least_squares(
        lambda t: _residuals(d, runs, s.curves(t), chassis),
        np.clip(start, s.low, s.high),
        bounds=(s.low, s.high),
        max_nfev=MAX_EVALUATIONS,
    )
    return np.asarray(result.x, dtype=float)


def _errors(
    d: TyreData, curves: tuple[AxleCurve, AxleCurve], chassis: Chassis, rows: np.ndarray
) -> np.ndarray:
    """Per run of ``rows``: the summed squared scaled errors, and the yaw-rate and lateral sums (3, R)."""
    runs = steady_start(d, d.runs.subset(rows), curves[1], chassis)
    beta, r = predict(runs, chassis, curves[0].force_per_load, curves[1].force_per_load)
    yaw = np.where(runs.scored, (r - runs.yaw_rate) ** 2, 0.0).sum(axis=1)
    lateral = np.where(runs.scored, np.nan_to_num((runs.speed * np.sin(beta) - runs.lateral) ** 2), 0.0).sum(
        axis=1
    )
    scaled = yaw / d.scales[0] ** 2 + (lateral / d.scales[1] ** 2 if d.slip else 0.0)
    return np.vstack([scaled, yaw, lateral])


@dataclass
class _Candidate:
    structure: _Structure | None  # None: the nominal tyres
    score: Score
    sums: np.ndarray  # held-out yaw-rate and lateral squared errors, (2,)
    final: np.ndarray | None
    servo: str  # the servo the wheel was run through (SERVO_SOURCES)


def _assess(
    s: _Structure | None,
    d: TyreData,
    folds: Folds,
    chassis: Chassis,
    nominal: tuple[AxleCurve, AxleCurve],
    servo: str = "identified",
) -> _Candidate:
    """Fit ``s`` on all the data and on each fold's training runs; score it on each held-out block."""
    n_runs = len(d.cover)
    train = np.array([[folds.train[f, c].all() for c in d.cover] for f in range(folds.count)]).reshape(
        folds.count, n_runs
    )
    test = folds.test[:, d.time]
    count = d.runs.scored.sum(axis=1)
    sse, sums = np.zeros(folds.count), np.zeros(2)
    final = None if s is None else _fit(s, d, np.arange(n_runs), chassis, s.start)
    for f in range(folds.count):
        curves = nominal if s is None or final is None else s.curves(_fit(s, d, train[f], chassis, final))
        errors = _errors(d, curves, chassis, np.flatnonzero(test[f]))
        sse[f], sums = errors[0].sum(), sums + errors[1:].sum(axis=1)
    counts = np.array([count[test[f]].sum() for f in range(folds.count)])
    name = ("nominal" if s is None else s.name) + ("" if servo == "identified" else f", {servo} servo")
    parameters = 0 if s is None else len(s.start)
    score = Score(name, parameters, sse, counts, bool(s and s.nonlinear))
    return _Candidate(s, score, sums, final, servo)


def _servo_variants(
    data: TransitionDataset, vehicle: VehicleParams, servo: IdentifiedModel, min_speed: float
) -> list[tuple[str, TyreData]]:
    """The data with the wheel run through the identified servo's lag alone and the nominal servo.

    For a servo fitted on the yaw rate (:func:`~rkmpc.learning.tyre_data.confounded`): its delay
    holds the chassis's lag in building up yaw, which a dynamic model has already.
    """
    out = []
    if servo.servo_delay > 0.0:
        out.append(("lag", prepare(data, vehicle, replace(servo, servo_delay=0.0), min_speed)))
    nominal = IdentifiedModel(vehicle.steering.time_constant, 0.0, math.nan, math.nan, 0, "nominal")
    out.append(("nominal", prepare(data, vehicle, nominal, min_speed)))
    return out


def identify_tyres(
    data: TransitionDataset,
    vehicle: VehicleParams,
    servo: IdentifiedModel | None = None,
    *,
    min_speed: float = 1.0,
    folds: int = DEFAULT_FOLDS,
) -> IdentifiedTyres:
    """The front and rear tyre curves of ``vehicle``'s chassis that ``data`` show, chosen on held-out blocks.

    Parameters
    ----------
    data : TransitionDataset
        Laps (transitions grouped in episodes) with speed and yaw rate, and the side slip and
        the wheel angle where measured.
    vehicle : VehicleParams
        The car's nominal model: its chassis (mass, yaw inertia, axle distances, height of the
        centre of gravity) is taken as known, its tyres are the nominal candidate.
    servo : IdentifiedModel, optional
        The servo that runs the wheel angle from the commands when it is not measured (the car's
        nominal servo when None).
    min_speed : float
        Transitions slower than this (m/s) at either end are left out (slip angles lose meaning).
    folds : int
        Time blocks of the cross-validation (>= 2).

    Returns
    -------
    IdentifiedTyres
        ``status`` ``identified``, or ``nominal`` with the reason (also an
        :class:`~rkmpc.core.errors.IdentificationWarning`, as is every other warning).

    Raises
    ------
    ParameterError
        For a bad argument.
    """
    if not is_positive_number(min_speed):
        raise ParameterError(f"identify_tyres: min_speed must be a positive number (m/s), got {min_speed!r}")
    if not is_integer(folds, 2):
        raise ParameterError(f"identify_tyres: folds must be an integer >= 2, got {folds!r}")
    if servo is None:
        servo = IdentifiedModel(vehicle.steering.time_constant, 0.0, math.nan, math.nan, 0, "nominal")
    d = prepare(data, vehicle, servo, min_speed)
    nominal, chassis = nominal_curves(vehicle), Chassis.of(vehicle)
    notes = limits(d, servo)
    n = int(d.usable.sum())
    base: dict[str, Any] = {
        "fitted_on": "slip_angle" if d.slip else "yaw_rate",
        "wheel": d.wheel,
        "servo": "identified",
        "n_samples": n,
        "slip_reach": d.reach,
    }
    blocks = time_blocks(d.usable, folds, max(1, round(GAP_SECONDS / data.dt)))
    reason = unexcited(d, n)
    if reason is None and blocks is None:
        reason = f"too few transitions ({n}) for held-out blocks: no fit can be checked"
    if reason is not None or blocks is None:
        return _finish(nominal, "nominal", reason or "", notes, base)
    nominal_c = _assess(None, d, blocks, chassis, nominal)
    structures = _structures(nominal, d.slip, scale=not confounded(d, servo))
    candidates = [nominal_c] + [_assess(s, d, blocks, chassis, nominal) for s in structures]
    if confounded(d, servo):  # the wheel run through servos without the chassis's lag: the scale shows
        every = _structures(nominal, d.slip, scale=True)
        for name, other in _servo_variants(data, vehicle, servo, min_speed):
            candidates += [_assess(s, other, blocks, chassis, nominal, name) for s in [None, *every]]
    base.update(
        folds=blocks.count,
        nominal_score=nominal_c.score.mse,
        candidates=tuple((c.score.name, c.score.mse) for c in candidates),
        **_rmse("nominal_", nominal_c, d),
    )
    while (chosen := choose([c.score for c in candidates], nominal_c.score)) is not nominal_c.score:
        candidate = next(c for c in candidates if c.score is chosen)
        s, final = candidate.structure, candidate.final
        base.update(servo=candidate.servo, heldout_score=chosen.mse, **_rmse("", candidate, d))
        if s is None or final is None:  # the nominal tyres, the wheel run through another servo
            reason = (
                f"the nominal tyres predict held-out data best with the wheel run through the "
                f"{candidate.servo} servo (score {chosen.mse:.4g}; through the identified one "
                f"{nominal_c.score.mse:.4g})"
            )
            return _finish(nominal, "nominal", reason, notes, base)
        if not (np.isclose(final, s.low, atol=1e-3) | np.isclose(final, s.high, atol=1e-3)).any():
            front, rear = s.curves(final)
            reason = (
                f"{s.name} predicts held-out data with a score {chosen.mse:.4g}, "
                f"the nominal tyres {nominal_c.score.mse:.4g}"
            )
            notes.extend(reach_notes(d, front, rear) if s.name == "pacejka" else [])
            return _finish((front, rear), s.name, reason, notes, base, status="identified")
        notes.append(f"tyres: the {s.name} fit ends on a bound of its parameters: dropped")
        candidates.remove(candidate)
    best = min((c for c in candidates if c is not nominal_c), key=lambda c: c.score.mse, default=None)
    reason = "no candidate predicts held-out data clearly better than the nominal tyres" + (
        f" (best {best.score.name}: score {best.score.mse:.4g}, nominal {nominal_c.score.mse:.4g})"
        if best
        else ""
    )
    base.update(servo="identified", heldout_score=nominal_c.score.mse, **_rmse("", nominal_c, d))
    return _finish(nominal, "nominal", reason, notes, base)


def _rmse(prefix: str, c: _Candidate, d: TyreData) -> dict[str, float]:
    total = float(np.sum(c.score.count))
    lateral = math.sqrt(c.sums[1] / total) if d.slip and total else math.nan
    return {
        f"{prefix}yaw_rate_rmse": math.sqrt(c.sums[0] / total) if total else math.nan,
        f"{prefix}lateral_velocity_rmse": lateral,
    }


def _finish(
    curves: tuple[AxleCurve, AxleCurve],
    structure: str,
    reason: str,
    notes: list[str],
    base: dict[str, Any],
    status: str = "nominal",
) -> IdentifiedTyres:
    if status == "nominal":
        notes.append(f"tyres: {reason}; the model keeps the car's nominal tyres (marked nominal)")
    base.setdefault("folds", 0)
    tyres = IdentifiedTyres(
        structure=structure,
        front=curves[0],
        rear=curves[1],
        status=status,
        status_reason=reason,
        warnings=tuple(notes),
        **base,
    )
    for note in tyres.warnings:
        warnings.warn(note, IdentificationWarning, stacklevel=3)
    return tyres
