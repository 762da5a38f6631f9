"""``rkmpc train``: a model of any recipe from a data set, saved to a file."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.core.errors import IdentificationWarning, ParameterError, RkmpcError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.labels import estimate_dataset
from rkmpc.estimation.steering import SteeringModel
from rkmpc.learning.contract import Provenance
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import IdentifiedModel, identify
from rkmpc.learning.learn import Learned, learn, save_learned
from rkmpc.learning.recipes import KoopmanLearner, ModelOutput, Recipe, recipe_of_kind
from rkmpc.learning.tyre_model import IdentifiedTyres
from rkmpc.vehicle.params import VehicleParams

__all__ = [
    "data_fell_short",
    "describe_heldout",
    "describe_identified",
    "describe_learned",
    "describe_tyres",
    "estimated_for",
    "identified_steering",
    "prediction_error_unit",
    "train_to_file",
]

#: The observation fields a Koopman model's data must measure to be learned from as they are.
_MEASURED = ("speed", "yaw_rate", "steer_angle")

#: The unit of each state feature a model may predict (:mod:`rkmpc.learning.features`).
_UNITS = {
    "x": "m",
    "y": "m",
    "yaw": "rad",
    "speed": "m/s",
    "yaw_rate": "rad/s",
    "slip_angle": "rad",
    "steer_angle": "rad",
    "previous_speed_command": "m/s",
    "previous_steer_command": "rad",
}


def prediction_error_unit(learner: KoopmanLearner) -> str:
    """What a Koopman model's held-out prediction error measures, with its units.

    The error of a prediction is the Euclidean norm over the model's outputs (its state features,
    or the nominal input ``U_p`` of a residual model), each in its own SI unit: ``"norm of x (m),
    y (m), yaw (rad)"``.
    """
    if learner.output is ModelOutput.NOMINAL_INPUT:
        parts = ["U_p speed (m/s)", "U_p wheel angle (rad)"]
    else:
        parts = [f"{name} ({_UNITS[name]})" for name in learner.state.names]
    return "norm of " + ", ".join(parts)


def estimated_for(
    recipe: Recipe, data: TransitionDataset, vehicle: VehicleParams, estimator: EstimatorConfig | None = None
) -> TransitionDataset:
    """The data a recipe learns from: as recorded, or the state estimator's smoothed estimates.

    A Koopman model learns from the data as they are where they measured speed, yaw rate and
    wheel angle exactly: the simulator's ideal sensors, or data whose origin is not recorded. It
    learns from the smoothed estimates of :func:`rkmpc.estimation.labels.estimate_dataset` (poses
    without jumps, speed and yaw rate without scale and bias; the wheel angle measured where it
    is, else propagated from the commands through the servo the data show,
    :func:`identified_steering`, which the model records and the driving controller's estimator
    then uses too) where one of them was never measured (no row has it: a car without a
    steering-angle sensor, the ``f1tenth-real`` sensors), and where the data say their sensors
    were not exact: a simulated car's sensor profile that is not ideal (``sensors_ideal`` false in
    the metadata of :func:`rkmpc.sim.collect.collect`, or in a part of a concatenation). The
    controller that drives with such sensors sees the estimator's states (it stands in front of
    it), so it learns from the same; from the raw data, a car that measures its wheel angle but
    has a localiser whose pose jumps would learn its labels from the jumps (``docs/sensors.md``).
    A log of a real car (a bag, a CSV log) says nothing of
    its sensors' exactness and is learned from as its fields say; the imports leave out the
    transitions across a pose jump. The smoother dates each pose back by the latency the data's
    metadata record (:func:`_pose_latency`). An identification learns from the data as recorded (it
    identifies the servo from the yaw rate's response to the commands).
    """
    if not isinstance(recipe.learner, KoopmanLearner):
        return data
    columns = [OBSERVATION_FIELDS.index(name) for name in _MEASURED]
    never = ~np.isfinite(data.obs[:, columns]).any(axis=0)
    if not never.any() and not _inexact_sensors(data.metadata):
        return data  # measured (a row where one is missing is for check_learnable to name)
    config = replace(estimator if estimator is not None else EstimatorConfig(), control_period=data.dt)
    return estimate_dataset(
        data,
        vehicle,
        steering=identified_steering(data, vehicle),
        config=config,
        pose_latency=_pose_latency(data.metadata),
    )


def _pose_latency(meta: Mapping[str, Any]) -> float:
    """How late (s) the data's poses were, as their metadata say (``pose_latency``, written by
    :func:`rkmpc.sim.collect.collect` from the sensor profile); 0 where they do not say (a log of a
    real car is taken as its stamps say).

    Raises
    ------
    ParameterError
        For a concatenation of parts with different latencies.
    """
    if "pose_latency" in meta:
        return float(meta["pose_latency"])
    parts = meta["parts"] if "parts" in meta and isinstance(meta["parts"], list) else []
    latencies = {_pose_latency(part) for part in parts if isinstance(part, Mapping)}
    if len(latencies) > 1:
        raise ParameterError(
            f"the data join parts whose poses were late by different times ({sorted(latencies)} s): "
            "estimate each part on its own"
        )
    return latencies.pop() if latencies else 0.0


def _inexact_sensors(meta: Mapping[str, Any]) -> bool:
    """Whether a data set's metadata say its sensors were not exact (:func:`estimated_for`): its
    ``sensors_ideal`` is false, or, for a concatenation, that of any of its parts."""
    if "sensors_ideal" in meta and meta["sensors_ideal"] is False:
        return True
    return (
        "parts" in meta
        and isinstance(meta["parts"], list)
        and any(isinstance(part, Mapping) and _inexact_sensors(part) for part in meta["parts"])
    )


def data_fell_short(data: TransitionDataset) -> str | None:
    """One line when the data's laps did not complete (:func:`rkmpc.sim.collect.collect`'s ``outcome``).

    A learned controller trained on LMPC laps that left the track learns from less than was asked
    (and from a car out of control at the end); it is said where the model is made, on the
    terminal, not only in the results. None for complete laps and for data of other sources.
    """
    meta = data.metadata
    outcome = meta["outcome"] if "outcome" in meta else None
    if outcome is None or outcome == "completed":
        return None
    who = meta["controller"] if "controller" in meta else "recorded"
    laps = f" of {meta['laps']}" if "laps" in meta else ""
    progress = f" after {float(meta['progress_laps']):.2f}{laps} laps" if "progress_laps" in meta else ""
    return (
        f"the {who} laps of the data did not complete ({outcome}{progress}; {len(data)} transitions): "
        "the model learns from less than was asked"
    )


def identified_steering(data: TransitionDataset, vehicle: VehicleParams) -> SteeringModel:
    """The steering servo the data show (:func:`rkmpc.learning.identification.identify`), or the
    car's nominal one where identification finds nothing better on held-out data (or cannot run)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            model = identify(data, vehicle)
    except RkmpcError:
        return SteeringModel.nominal(vehicle)
    if model.status != "identified":
        return SteeringModel.nominal(vehicle)
    return SteeringModel.from_identified(model, vehicle.steering.max_angle)


def describe_identified(model: IdentifiedModel) -> str:
    """One line: the servo structure and parameters, the understeer gradient, what they were fitted on."""
    servo = f"servo {model.servo_structure}: tau {model.servo_time_constant:.3f} s"
    if model.servo_delay > 0:
        servo += f", delay {1000 * model.servo_delay:.0f} ms"
    if model.servo_rate_limit is not None:
        servo += f", rate limit {model.servo_rate_limit:.2f} rad/s"
    signal = {"steer_angle": "the measured wheel angle", "yaw_rate": "the yaw rate"}.get(
        model.fitted_on or ""
    )
    fitted = f", fitted on {signal}" if signal else ""
    return (
        f"identified {servo}; understeer K {model.understeer_gradient:.4f} s^2/m; "
        f"{model.n_samples} transitions{fitted}"
    )


def describe_heldout(model: IdentifiedModel) -> str:
    """One line: how well the model predicts held-out data against the nominal model, and its status."""
    if model.status == "unchecked":
        return "status unchecked: never compared with the nominal model on held-out data"
    parts = []
    if math.isfinite(model.heldout_rmse):
        parts.append(
            f"held-out yaw rate {model.heldout_rmse:.4f} rad/s RMS, nominal model {model.nominal_rmse:.4f} "
            f"(ratio {model.error_ratio:.2f}, R^2 {model.heldout_r2:.3f})"
        )
    if math.isfinite(model.wheel_heldout_rmse):
        parts.append(
            f"held-out wheel angle {model.wheel_heldout_rmse:.4f} rad RMS, "
            f"nominal {model.wheel_nominal_rmse:.4f}"
        )
    figures = "; ".join(parts) if parts else "no held-out figure"
    return f"status {model.status} ({model.folds} time blocks): {figures}"


def describe_tyres(tyres: IdentifiedTyres) -> str:
    """One line: the tyre structure, both curves, the implied understeer and the held-out figures."""
    signal = {"slip_angle": "yaw rate and side slip", "yaw_rate": "the yaw rate alone"}[tyres.fitted_on]
    lateral = (
        f", lateral velocity {tyres.lateral_velocity_rmse:.4f} m/s "
        f"(nominal {tyres.nominal_lateral_velocity_rmse:.4f})"
        if math.isfinite(tyres.lateral_velocity_rmse)
        else ""
    )
    wheel = "measured" if tyres.wheel == "measured" else f"run through the {tyres.servo} servo"
    return (
        f"tyres {tyres.status} ({tyres.structure}, fitted on {signal}, wheel {wheel}): "
        f"front {tyres.front.describe()}, rear {tyres.rear.describe()}; "
        f"implied K {tyres.understeer_gradient():.4f} s^2/m; "
        f"slip angles reached {tyres.slip_reach[0]:.3f} / {tyres.slip_reach[1]:.3f} rad; "
        f"held-out score {tyres.heldout_score:.4g} against the nominal tyres' {tyres.nominal_score:.4g} "
        f"({tyres.folds} blocks): yaw rate {tyres.yaw_rate_rmse:.4f} rad/s "
        f"(nominal {tyres.nominal_yaw_rate_rmse:.4f}){lateral}"
    )


def train_to_file(
    data: TransitionDataset,
    made_for: Provenance,
    vehicle: VehicleParams,
    kind: str,
    out: str | Path,
    *,
    seed: int = 0,
    epochs: int | None = None,
    on_epoch: Callable[[int, float], None] | None = None,
    allow_mismatch: bool = False,
    source: str = "the data set",
    estimator: EstimatorConfig | None = None,
) -> list[str]:
    """Identify or train the model of ``kind`` on ``data`` and write it to ``out``.

    The data set's contract is checked against ``made_for`` first
    (:meth:`rkmpc.learning.contract.Provenance.check`).

    Parameters
    ----------
    data : TransitionDataset
        The data set (on-track laps, or random excitation for ``koopman``).
    made_for : Provenance
        The car (vehicle name, wheelbase of the nominal kinematic model, m) and the control
        period (s) the model is for.
    vehicle : VehicleParams
        The car's nominal parameters: what servo identification falls back to when the data
        do not support a fit.
    kind : str
        Model kind of a recipe (:func:`rkmpc.learning.recipes.model_kinds`).
    out : str or Path
        Model file (JSON for ``identified``, ``.npz`` archive otherwise).
    seed : int
        Seed of the augmentation and the training.
    epochs : int or None
        Training epochs (None: the recipe's default).
    on_epoch : callable, optional
        Progress callback ``(epoch, loss)``.
    allow_mismatch : bool
        Train on data of another car or period anyway (the warnings are kept in the model file).
    source : str
        Name of the data set in messages (its file).
    estimator : EstimatorConfig or None
        The tuning of the state estimator whose smoother fills the fields the data never measured
        (:func:`estimated_for`); the car's (``CarConfig.estimator``), so that the model learns from
        the states its controller's estimator will give it. None: the defaults.

    Returns
    -------
    list of str
        A summary of what was written, line by line: first a ``warning:`` line when the data's laps
        did not complete (:func:`data_fell_short`); for an identified model, its parameters,
        its held-out quality against the nominal model, a ``MARKED NOMINAL:`` line when it is the
        nominal model, and one ``warning:`` line per identification warning.

    Raises
    ------
    ContractError, InputFileError
        As :func:`rkmpc.learning.learn.learn`, which makes the model: data of another car, wheelbase
        or period (unless ``allow_mismatch``), or data no model should be learned from.
    """
    if made_for.wheelbase != vehicle.wheelbase:
        raise ParameterError("train_to_file: made_for must give the wheelbase of the car's vehicle")
    recipe = recipe_of_kind(kind)
    learned = learn(
        recipe,
        estimated_for(recipe, data, vehicle, estimator),
        made_for=made_for,
        vehicle=vehicle,
        seed=seed,
        epochs=epochs,
        on_epoch=on_epoch,
        allow_mismatch=allow_mismatch,
        source=source,
    )
    save_learned(learned, out)
    short = data_fell_short(data)
    return ([] if short is None else [f"warning: {short}"]) + describe_learned(learned, out)


def describe_learned(learned: Learned, out: str | Path) -> list[str]:
    """What ``rkmpc train`` prints of a model it wrote: a summary line, then its warnings."""
    model, report = learned.model, learned.report
    if isinstance(model, IdentifiedModel):
        loud = [f"MARKED NOMINAL: {model.status_reason}"] if model.status == "nominal" else []
        tyres = model.tyres
        if tyres is not None and tyres.status == "nominal":
            loud.append(f"TYRES MARKED NOMINAL: {tyres.status_reason}")
        return [
            f"{describe_identified(model)} -> {out}",
            describe_heldout(model),
            *([describe_tyres(tyres)] if tyres is not None else []),
            *loud,
            *(f"warning: {w}" for w in learned.warnings),
        ]
    lines = [*learned.warnings]
    if report is not None:
        lines.append(
            f"{learned.recipe.kind} model: {report.raw_count} raw -> {report.augmented_count} augmented "
            f"samples, {report.fit_time_s:.1f} s -> {out}"
        )
        err = report.multi_step_error
        if err and isinstance(learned.recipe.learner, KoopmanLearner):
            steps = [k for k in (1, 10, len(err)) if k <= len(err)]
            unit = prediction_error_unit(learned.recipe.learner)
            lines.append(f"held-out prediction error ({unit}): {_at_steps(err, steps)}")
            none = report.no_correction_error
            if len(none) == len(err):
                lines.append(f"no correction (U_p = the command), same windows: {_at_steps(none, steps)}")
    return lines


def _at_steps(errors: list[float], steps: list[int]) -> str:
    """``errors`` (one per horizon step) at the given steps (counted from 1), in words."""
    return ", ".join(f"{errors[k - 1]:.4f} at step {k}" for k in steps)
