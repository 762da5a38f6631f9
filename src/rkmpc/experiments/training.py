"""``rkmpc train``: a model of any recipe from a data set, saved to a file."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import identify
from rkmpc.learning.io import save_identified
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.learning.recipes import recipe_of_kind

__all__ = ["train_to_file"]


def train_to_file(
    data: TransitionDataset,
    wheelbase: float,
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
    wheelbase : float
        Wheelbase of the nominal kinematic model (m).
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
        A summary of what was written, line by line.
    """
    recipe = recipe_of_kind(kind)
    if recipe.learner == "identification":
        ident = identify(data, wheelbase)
        save_identified(ident, out, {"data_hash": data.content_hash(), "data_metadata": data.metadata})
        return [f"{ident} -> {out}"]
    config = TrainConfig(kind=kind, augment=recipe.augment(seed), model=recipe.default_model(seed, epochs))
    model, report = train_model(data, wheelbase, config, on_epoch=on_epoch)
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
