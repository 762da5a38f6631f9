"""``rkmpc train``: a model of any recipe from a data set, saved to a file."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import IdentifiedModel, identify
from rkmpc.learning.io import save_identified
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.vehicle.params import VehicleParams

__all__ = ["describe_identified", "train_to_file"]


def describe_identified(model: IdentifiedModel) -> str:
    """One line: the servo structure and parameters, the understeer gradient, the fits' R^2."""
    servo = f"servo {model.servo_structure}: tau {model.servo_time_constant:.3f} s"
    if model.servo_delay > 0:
        servo += f", delay {1000 * model.servo_delay:.0f} ms"
    if model.servo_rate_limit is not None:
        servo += f", rate limit {model.servo_rate_limit:.2f} rad/s"
    return (
        f"identified {servo} (R^2 {model.servo_fit_r2:.3f}); understeer K {model.understeer_gradient:.4f} "
        f"s^2/m (R^2 {model.understeer_fit_r2:.3f}); {model.n_samples} transitions"
    )


def train_to_file(
    data: TransitionDataset,
    vehicle: VehicleParams,
    kind: str,
    out: str | Path,
    *,
    seed: int = 0,
    epochs: int | None = None,
    on_epoch: Callable[[int, float], None] | None = None,
) -> list[str]:
    """Identify or train the model of ``kind`` on ``data`` and write it to ``out``.

    Parameters
    ----------
    data : TransitionDataset
        The data set (on-track laps, or random excitation for ``koopman``).
    vehicle : VehicleParams
        The car's nominal parameters: the wheelbase of the kinematic model (m), and the
        servo identification falls back to when the data do not support a fit.
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

    Returns
    -------
    list of str
        A summary of what was written, line by line; for an identified model, one
        ``warning:`` line per identification warning.
    """
    recipe = recipe_of_kind(kind)
    if recipe.learner == "identification":
        ident = identify(data, vehicle)
        save_identified(ident, out, {"data_hash": data.content_hash(), "data_metadata": data.metadata})
        return [f"{describe_identified(ident)} -> {out}", *(f"warning: {w}" for w in ident.warnings)]
    config = TrainConfig(kind=kind, augment=recipe.augment(seed), model=recipe.default_model(seed, epochs))
    model, report = train_model(data, vehicle.wheelbase, config, on_epoch=on_epoch)
    model.save(out, metadata=model.metadata_)
    lines = [
        f"{kind} model: {report.raw_count} raw -> {report.augmented_count} augmented samples, "
        f"{report.fit_time_s:.1f} s -> {out}"
    ]
    err = report.multi_step_error
    if err:
        steps = [k for k in (1, 10, len(err)) if k <= len(err)]
        lines.append(
            "held-out prediction error: " + ", ".join(f"{err[k - 1]:.4f} at step {k}" for k in steps)
        )
    return lines
