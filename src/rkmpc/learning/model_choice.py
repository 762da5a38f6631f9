"""The identified model chosen on held-out blocks: from the yaw rate, or from a measured wheel angle.

Both ways compare their candidates with the car's nominal model (its data-sheet
servo, ``K = 0``) on the same held-out blocks (:mod:`rkmpc.learning.heldout`)
and keep the nominal model, marked ``status = "nominal"`` with the reason, when
no candidate predicts clearly better:

* :func:`from_yaw`: every servo structure, with ``K`` fitted or 0, and the nominal
  servo with ``K`` fitted or 0, each fitted to the yaw rate with the wheel run
  from the commands (:mod:`rkmpc.learning.yaw_fit`), scored on the held-out yaw rate.
* :func:`from_wheel`: the servo structures fitted one step ahead on the measured
  wheel angle, scored on the held-out wheel angle run from the commands
  (:func:`~rkmpc.learning.servo_fit.heldout_servo_scores`); ``K`` fitted on the yaw
  rate given the measured wheel, scored on the held-out yaw rate. The model's
  headline figure is then the held-out yaw rate of both together, run from the
  commands, against the nominal model's.

A final fit with a parameter on an implausible bound is dropped and the choice made
again without it, with a warning.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rkmpc.learning.heldout import Folds, Score, choose, heldout_r2
from rkmpc.learning.identified_model import IdentifiedModel
from rkmpc.learning.servo_fit import OneStepProblem, ServoFit, fit_servo, heldout_servo_scores
from rkmpc.learning.servo_model import SERVO_STRUCTURES, ServoParameter, ServoStructure, bound_hits, r_squared
from rkmpc.learning.understeer import understeer_excess
from rkmpc.learning.yaw_fit import ServoInput, YawTarget, yaw_candidates

__all__ = [
    "MIN_LATERAL_ACCELERATION",
    "MIN_WHEEL_MOTION",
    "IdentificationData",
    "from_wheel",
    "from_yaw",
    "nominal_model",
]

#: RMS change per period (rad) below which the wheel angle (or the command) does not excite the servo.
MIN_WHEEL_MOTION = 1e-3
#: RMS lateral acceleration (m/s^2) below which the understeer gradient is not identifiable.
MIN_LATERAL_ACCELERATION = 0.2
#: Samples the understeer fit needs at least.
_MIN_CORNERING_SAMPLES = 20
_KINEMATIC = "using K = 0 (the kinematic model)"
_STRUCTURES = {s.name: s for s in SERVO_STRUCTURES}


@dataclass(frozen=True, kw_only=True)
class IdentificationData:
    """A data set read for identification; arrays of shape (N,), one entry per transition.

    Parameters
    ----------
    servo : ServoInput
        The steering commands and episode starts.
    yaw : YawTarget
        Speed and yaw rate at the end of each transition (NaN where not usable).
    steer, steer_next : numpy.ndarray
        Measured wheel angle (rad) at the start and the end of each transition, NaN where not measured.
    wheel_ok, yaw_ok : numpy.ndarray
        Transitions usable by the wheel-angle fit and by the yaw-rate fit (bool).
    parameters : dict of str to ServoParameter
        The plausible servo of the car.
    nominal : dict of str to float
        The car's nominal servo: ``delay`` (s), ``time_constant`` (s), ``rate_limit`` (rad/s).
    notes : list of str
        Warnings gathered so far.
    """

    servo: ServoInput
    yaw: YawTarget
    steer: np.ndarray
    steer_next: np.ndarray
    wheel_ok: np.ndarray
    yaw_ok: np.ndarray
    parameters: dict[str, ServoParameter]
    nominal: dict[str, float]
    notes: list[str] = field(default_factory=list)

    @property
    def keep(self) -> str:
        """The nominal servo, in words."""
        return f"using the nominal first-order lag of {self.nominal['time_constant']:g} s"


def nominal_model(d: IdentificationData, n_samples: int, reason: str, **quality: Any) -> IdentifiedModel:
    """The car's nominal model (its servo, ``K = 0``), marked nominal for ``reason`` (also a warning)."""
    return IdentifiedModel(
        d.nominal["time_constant"],
        0.0,
        math.nan,
        math.nan,
        n_samples,
        "nominal",
        warnings=(
            *d.notes,
            f"identification: {reason}; the model is marked nominal (the car's nominal servo, K = 0)",
        ),
        status="nominal",
        status_reason=reason,
        **quality,
    )


def _model(
    d: IdentificationData,
    n_samples: int,
    structure: ServoStructure | None,
    values: dict[str, float],
    gradient: float,
    r2: tuple[float, float],
    reason: str,
    **quality: Any,
) -> IdentifiedModel:
    """An identified model: ``structure`` (None: the nominal servo) with ``values``, and ``K``."""
    fitted = () if structure is None else structure.fitted
    return IdentifiedModel(
        values["time_constant"] if structure else d.nominal["time_constant"],
        gradient,
        r2[0],
        r2[1],
        n_samples,
        structure.name if structure else "nominal",
        values["delay"] if "delay" in fitted else 0.0,
        values["rate_limit"] if "rate_limit" in fitted else None,
        tuple(d.notes),
        status="identified",
        status_reason=reason,
        **quality,
    )


def _no_better(scores: Sequence[Score], nominal: Score, signal: str, unit: str) -> str:
    others = [s for s in scores if s is not nominal]
    if not others:
        return (
            f"no candidate but the nominal model was fitted (held-out {signal} {nominal.rmse:.4g} {unit} RMS)"
        )
    best = min(others, key=lambda s: s.mse)
    return (
        f"no plausible candidate predicts the held-out {signal} clearly better than the nominal model "
        f"(best {best.name}: {best.rmse:.4g} {unit} RMS, nominal {nominal.rmse:.4g})"
    )


def _cornering(d: IdentificationData, usable: np.ndarray) -> str | None:
    """Why ``K`` cannot be identified on the ``usable`` samples, or None when it can."""
    if usable.sum() < _MIN_CORNERING_SAMPLES:
        return (
            f"understeer: only {int(usable.sum())} transitions with a yaw rate faster than the minimum speed "
            f"(at least {_MIN_CORNERING_SAMPLES}); {_KINEMATIC}"
        )
    a_lat = float(np.sqrt(np.mean((d.yaw.speed[usable] * d.yaw.yaw_rate[usable]) ** 2)))
    if a_lat < MIN_LATERAL_ACCELERATION:
        return (
            f"understeer: the car hardly corners ({a_lat:.2f} m/s^2 lateral acceleration RMS, less than "
            f"{MIN_LATERAL_ACCELERATION:g}): not identifiable; {_KINEMATIC}"
        )
    return None


def _gradient_note(d: IdentificationData, gradient: float) -> None:
    """Say so when the least-squares ``K`` was beyond its plausible range and is held at a bound."""
    for bound in d.yaw.gradient_bounds:
        if gradient != 0.0 and abs(gradient - bound) <= 1e-12 * max(1.0, abs(bound)):
            low, high = d.yaw.gradient_bounds
            d.notes.append(
                f"understeer: the fit gives K beyond the plausible [{low:.4f}, {high:g}] s^2/m "
                "(rad per m/s^2; "
                f"the lower end also keeps the car below its critical speed); held at {bound:g}"
            )


def _still(change: np.ndarray, usable: np.ndarray, what: str, d: IdentificationData) -> str | None:
    """Why the servo cannot be identified from ``change`` (per period), or None when it can."""
    motion = float(np.std(change[usable])) if usable.any() else 0.0
    if motion >= MIN_WHEEL_MOTION:
        return None
    return (
        f"servo: {what} barely moves ({motion:.1e} rad per period RMS, less than {MIN_WHEEL_MOTION:g}): "
        f"not identifiable; {d.keep}"
    )


def from_yaw(d: IdentificationData, folds: Folds) -> IdentifiedModel:
    """Servo and ``K`` fitted to the yaw rate and chosen on the held-out blocks of ``folds``."""
    usable = d.yaw_ok
    commands = d.servo.commands
    still = _still(commands[:, 0] - commands[:, 1], usable, "the steering command", d)
    flat = _cornering(d, usable)
    d.notes.extend(n for n in (still, flat) if n)
    candidates = yaw_candidates(
        d.servo, d.yaw, folds, d.parameters, d.nominal, servo_structures=() if still else SERVO_STRUCTURES
    )
    candidates = [c for c in candidates if not (flat and c.fit_gradient)]
    nominal = candidates[0].score
    quality = {
        "fitted_on": "yaw_rate",
        "folds": folds.count,
        "nominal_rmse": nominal.rmse,
        "heldout_candidates": tuple((c.score.name, c.score.rmse) for c in candidates),
    }
    while True:
        chosen = choose([c.score for c in candidates], nominal)
        if chosen is nominal:
            reason = _no_better([c.score for c in candidates], nominal, "yaw rate", "rad/s")
            return nominal_model(
                d, int(usable.sum()), reason, heldout_rmse=nominal.rmse, **_r2(nominal, d, folds), **quality
            )
        candidate = next(c for c in candidates if c.score is chosen)
        values, gradient, pred = candidate.fit(d.servo, d.yaw, usable, d.parameters, d.nominal)
        hits = () if candidate.structure is None else bound_hits(d.parameters, candidate.structure, values)
        if not hits:
            break
        d.notes.append(f"servo: the fit {chosen.name} ends with {', '.join(hits)}: dropped")
        candidates.remove(candidate)
    servo_r2 = r_squared(d.yaw.yaw_rate[usable], pred[usable]) if candidate.structure else math.nan
    _gradient_note(d, gradient)
    reason = (
        f"{chosen.name} predicts the held-out yaw rate with {chosen.rmse:.4g} rad/s RMS, "
        f"the nominal model with {nominal.rmse:.4g}"
    )
    return _model(
        d,
        int(usable.sum()),
        candidate.structure,
        values,
        gradient,
        (servo_r2, math.nan),
        reason,
        heldout_rmse=chosen.rmse,
        **_r2(chosen, d, folds),
        **quality,
    )


def _r2(score: Score, d: IdentificationData, folds: Folds) -> dict[str, float]:
    return {"heldout_r2": heldout_r2(score, d.yaw.yaw_rate, folds)}


def from_wheel(d: IdentificationData, folds: Folds) -> IdentifiedModel:
    """Servo fitted on the measured wheel angle, ``K`` on the yaw rate, each chosen on held-out blocks."""
    rows = np.flatnonzero(d.wheel_ok)
    servo, fold_values, wheel_quality = _wheel_servo(d, folds, rows)
    gradients, k_r2 = _wheel_gradient(d, folds)
    quality: dict[str, Any] = {"fitted_on": "steer_angle", "folds": folds.count, **wheel_quality}
    # The headline: the held-out yaw rate with the wheel run from the commands, against the nominal model.
    yaw_folds = folds.restricted(d.yaw_ok)
    if yaw_folds.test.any():
        count = yaw_folds.test.sum(axis=1)
        nominal_wheel = d.servo.wheel({k: np.full(folds.count, v) for k, v in d.nominal.items()})
        model = Score(
            "model", 0, d.yaw.heldout_sse(d.servo.wheel(fold_values), gradients[:-1], yaw_folds.test), count
        )
        base = Score(
            "nominal", 0, d.yaw.heldout_sse(nominal_wheel, np.zeros(folds.count), yaw_folds.test), count
        )
        quality.update(
            heldout_rmse=model.rmse,
            nominal_rmse=base.rmse,
            heldout_r2=heldout_r2(model, d.yaw.yaw_rate, yaw_folds),
        )
    gradient = float(gradients[-1])
    if servo is None and gradient == 0.0:
        reason = (
            "neither the servo nor the understeer gradient predicts held-out data clearly better than nominal"
        )
        return nominal_model(d, len(rows), reason, **quality)
    if servo is None:
        reason = "K predicts the held-out yaw rate clearly better than K = 0; the servo is the nominal one"
        return _model(d, len(rows), None, {}, gradient, (math.nan, k_r2), reason, **quality)
    values = {
        "delay": servo.delay,
        "time_constant": servo.time_constant,
        "rate_limit": servo.rate_limit or 0.0,
    }
    reason = (
        f"servo {servo.structure} predicts the held-out wheel angle with "
        f"{quality['wheel_heldout_rmse']:.4g} rad RMS, the nominal one with "
        f"{quality['wheel_nominal_rmse']:.4g}"
    )
    structure = _STRUCTURES[servo.structure]
    return _model(d, len(rows), structure, values, gradient, (servo.r2, k_r2), reason, **quality)


def _wheel_servo(
    d: IdentificationData, folds: Folds, rows: np.ndarray
) -> tuple[ServoFit | None, dict[str, np.ndarray], dict[str, Any]]:
    """The servo chosen on the held-out wheel angle (None: the nominal one), the servo of each
    held-out fit (shape (F,) each), and the held-out figures."""
    delta, delta_next, commands = d.steer[rows], d.steer_next[rows], d.servo.commands[rows]
    still = _still(d.steer_next - d.steer, d.wheel_ok, "the wheel angle", d)
    fold_values = {name: np.full(folds.count, value) for name, value in d.nominal.items()}
    error = np.nan_to_num((d.steer_next - d.servo.wheel(fold_values)) ** 2)
    nominal = Score("nominal", 0, np.einsum("fn,fn->f", error, folds.test), folds.test.sum(axis=1))
    problem = OneStepProblem(delta, delta_next, commands, d.servo.dt, d.parameters)
    structures = () if still else SERVO_STRUCTURES
    fits = heldout_servo_scores(problem, rows, folds, d.servo.wheel, d.steer_next, structures)
    by_name = {score.name: (structure, values) for structure, score, values in fits}
    scores = [nominal, *(score for _, score, _ in fits)]
    quality = {
        "wheel_nominal_rmse": nominal.rmse,
        "heldout_candidates": tuple((s.name, s.rmse) for s in scores),
    }
    while (chosen := choose(scores, nominal)) is not nominal:
        structure, values = by_name[chosen.name]
        servo = fit_servo(
            delta, delta_next, commands, d.servo.dt, parameters=d.parameters, structures=(structure,)
        )[0]
        if not servo.at_bound:
            held = {name: v[: folds.count] for name, v in values.items()}
            return servo, held, {**quality, "wheel_heldout_rmse": chosen.rmse}
        d.notes.append(f"servo: the fit {chosen.name} ends with {', '.join(servo.at_bound)}: dropped")
        scores.remove(chosen)
    d.notes.append(still or f"servo: {_no_better(scores, nominal, 'wheel angle', 'rad')}; {d.keep}")
    return None, fold_values, {**quality, "wheel_heldout_rmse": nominal.rmse}


def _wheel_gradient(d: IdentificationData, folds: Folds) -> tuple[np.ndarray, float]:
    """K of each fit (shape (F + 1,), the last on all the data; zeros when K = 0 is kept), in-sample R^2.

    Fitted on the yaw rate given the measured wheel angle and kept when it predicts the held-out
    yaw rate clearly better than ``K = 0``.
    """
    yaw_folds = folds.restricted(d.yaw_ok & np.isfinite(d.steer_next))
    zero = np.zeros(folds.count + 1)
    flat = _cornering(d, yaw_folds.train[-1])
    if flat:
        d.notes.append(flat)
        return zero, math.nan
    measured = np.nan_to_num(d.steer_next)[None, :]
    count = yaw_folds.test.sum(axis=1)
    scores = []
    for fit in (False, True):
        _, sse, _ = d.yaw.squared_errors(measured, yaw_folds.train, yaw_folds.test, fit)
        scores.append(Score("K" if fit else "K = 0", int(fit), sse[0], count))
    if choose(scores, scores[0]) is scores[0]:
        d.notes.append(f"understeer: {_no_better(scores[1:], scores[0], 'yaw rate', 'rad/s')}; {_KINEMATIC}")
        return zero, math.nan
    gradients = d.yaw.squared_errors(measured, yaw_folds.train, yaw_folds.test, True)[2][0]
    _gradient_note(d, float(gradients[-1]))
    usable = yaw_folds.train[-1]
    speed, yaw_rate = d.yaw.speed[usable], d.yaw.yaw_rate[usable]
    excess = understeer_excess(d.steer_next[usable], speed, yaw_rate, d.yaw.wheelbase)
    return gradients, r_squared(excess, gradients[-1] * speed * yaw_rate)
