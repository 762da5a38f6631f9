"""``rkmpc train``: a model of any recipe from a data set, saved to a file."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from rkmpc.core.errors import ParameterError
from rkmpc.learning.contract import CONTRACT_KEY, Provenance
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.plausibility import check_learnable
from rkmpc.learning.identification import IdentifiedModel, identify
from rkmpc.learning.io import save_identified
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.vehicle.params import VehicleParams

__all__ = ["describe_heldout", "describe_identified", "train_to_file"]


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

    Returns
    -------
    list of str
        A summary of what was written, line by line; for an identified model, its parameters,
        its held-out quality against the nominal model, a ``MARKED NOMINAL:`` line when it is the
        nominal model, and one ``warning:`` line per identification warning.

    Raises
    ------
    ContractError
        When the data were recorded with another car, wheelbase or period, unless ``allow_mismatch``.
    InputFileError
        For data no model should be learned from (:func:`rkmpc.learning.data.plausibility.check_learnable`).
    """
    recipe = recipe_of_kind(kind)
    if made_for.wheelbase is None:
        raise ParameterError("train_to_file: made_for must give the wheelbase of the car")
    wheelbase = made_for.wheelbase
    if recipe.learner == "identification":
        warned = data.contract.check(made_for, source=source, made="recorded", allow_mismatch=allow_mismatch)
        check_learnable(data, wheelbase, source)
        ident = identify(data, vehicle)
        contract = replace(data.contract, dt=data.dt, wheelbase=wheelbase, recorded=True)
        metadata = {
            "data_hash": data.content_hash(),
            "data_metadata": data.metadata,
            CONTRACT_KEY: contract.to_json(),
            "contract_warnings": list(warned),
        }
        save_identified(ident, out, metadata)
        loud = [f"MARKED NOMINAL: {ident.status_reason}"] if ident.status == "nominal" else []
        return [
            f"{describe_identified(ident)} -> {out}",
            describe_heldout(ident),
            *loud,
            *warned,
            *(f"warning: {w}" for w in ident.warnings),
        ]
    config = TrainConfig(
        kind=kind, augment=recipe.augment(seed), model=recipe.default_model(seed, epochs), dt=made_for.dt
    )
    model, report = train_model(
        data,
        wheelbase,
        config,
        on_epoch=on_epoch,
        vehicle=made_for.vehicle,
        allow_mismatch=allow_mismatch,
        source=source,
    )
    model.save(out, metadata=model.metadata_)
    lines = [
        *model.metadata_["contract_warnings"],
        f"{kind} model: {report.raw_count} raw -> {report.augmented_count} augmented samples, "
        f"{report.fit_time_s:.1f} s -> {out}",
    ]
    err = report.multi_step_error
    if err:
        steps = [k for k in (1, 10, len(err)) if k <= len(err)]
        lines.append(
            "held-out prediction error: " + ", ".join(f"{err[k - 1]:.4f} at step {k}" for k in steps)
        )
    return lines
