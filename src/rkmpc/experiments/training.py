"""``rkmpc train``: a model of any recipe from a data set, saved to a file."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from rkmpc.core.errors import ParameterError
from rkmpc.learning.contract import Provenance
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.learn import Learned, learn, save_learned
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.vehicle.params import VehicleParams

__all__ = ["describe_identified", "describe_learned", "train_to_file"]


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
        A summary of what was written, line by line; for an identified model, one
        ``warning:`` line per identification warning.

    Raises
    ------
    ContractError
        When the data were recorded with another car, wheelbase or period, unless ``allow_mismatch``.
    InputFileError
        For data no model should be learned from (:func:`rkmpc.learning.data.plausibility.check_learnable`).
    """
    if made_for.wheelbase != vehicle.wheelbase:
        raise ParameterError("train_to_file: made_for must give the wheelbase of the car's vehicle")
    learned = learn(
        recipe_of_kind(kind),
        data,
        made_for=made_for,
        vehicle=vehicle,
        seed=seed,
        epochs=epochs,
        on_epoch=on_epoch,
        allow_mismatch=allow_mismatch,
        source=source,
    )
    save_learned(learned, out)
    return describe_learned(learned, out)


def describe_learned(learned: Learned, out: str | Path) -> list[str]:
    """What ``rkmpc train`` prints of a model it wrote: a summary line, then its warnings."""
    model, report = learned.model, learned.report
    if isinstance(model, IdentifiedModel):
        return [f"{describe_identified(model)} -> {out}", *(f"warning: {w}" for w in learned.warnings)]
    lines = [*learned.warnings]
    if report is not None:
        lines.append(
            f"{learned.recipe.kind} model: {report.raw_count} raw -> {report.augmented_count} augmented "
            f"samples, {report.fit_time_s:.1f} s -> {out}"
        )
        err = report.multi_step_error
        if err:
            steps = [k for k in (1, 10, len(err)) if k <= len(err)]
            lines.append(
                "held-out prediction error: " + ", ".join(f"{err[k - 1]:.4f} at step {k}" for k in steps)
            )
    return lines
