"""The one place that decides how a model is made from data: :func:`learn`, :func:`save_learned`.

A recipe's learner (:mod:`rkmpc.learning.recipes`) says what kind of model it is; :func:`learn`
trains a Koopman model (:func:`rkmpc.learning.pipeline.train_model`) or identifies the physical
parameters (:func:`rkmpc.learning.identification.identify`, and the tyres with
:func:`rkmpc.learning.tyre_fit.identify_tyres` when the learner asks for them), after the same
checks of the data (the contract: car, period, wheelbase; and that the data can be learned
from), and returns a :class:`Learned` that :func:`save_learned` writes to the model file of its
kind. ``rkmpc train``, the comparison, the studies and the on-car workflow all learn here.

Learning runs with numpy's BLAS on :data:`~rkmpc.learning.koopman.settings.TRAINING_THREADS` (1)
thread, as torch does: a threaded BLAS sums in an order that depends on the machine's cores, and a
least-squares fit of 50,000 samples then differs in its last digit, enough to change the laps a
model drives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from threadpoolctl import threadpool_limits

from rkmpc.core.errors import NotLearnedError
from rkmpc.learning.contract import CONTRACT_KEY, Provenance
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.plausibility import check_learnable
from rkmpc.learning.identification import IdentifiedModel, identify
from rkmpc.learning.io import save_identified
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.koopman.settings import TRAINING_THREADS
from rkmpc.learning.pipeline import TrainConfig, TrainReport, train_model
from rkmpc.learning.recipes import KoopmanLearner, Recipe
from rkmpc.learning.tyre_fit import identify_tyres
from rkmpc.vehicle.params import VehicleParams

__all__ = ["Learned", "learn", "save_learned"]


@dataclass(frozen=True, kw_only=True)
class Learned:
    """A model made from data, and what was learned on the way.

    Parameters
    ----------
    recipe : Recipe
        The recipe it was made by.
    model : KoopmanModel or IdentifiedModel
        The model.
    report : TrainReport or None
        What training did (a Koopman model), None for an identification.
    warnings : tuple of str
        Allowed contract mismatches and the identification's warnings.
    metadata : dict
        What the model file records beside the model (the data's hash and metadata, the contract).
    """

    recipe: Recipe
    model: KoopmanModel | IdentifiedModel
    report: TrainReport | None
    warnings: tuple[str, ...]
    metadata: dict[str, Any]


def learn(
    recipe: Recipe,
    data: TransitionDataset,
    *,
    made_for: Provenance,
    vehicle: VehicleParams,
    seed: int = 0,
    epochs: int | None = None,
    model: KoopmanModel | None = None,
    augment: AugmentConfig | None = None,
    on_epoch: Callable[[int, float], None] | None = None,
    allow_mismatch: bool = False,
    source: str = "the data set",
) -> Learned:
    """Make the model of ``recipe`` from ``data``.

    Parameters
    ----------
    recipe : Recipe
        What to make.
    data : TransitionDataset
        On-track laps (or random excitation for an ``"excitation"`` recipe).
    made_for : Provenance
        The car (preset name, wheelbase) and the control period the model is for; the data's
        contract is checked against it.
    vehicle : VehicleParams
        The car's nominal parameters (the kinematic model's wheelbase; what identification falls
        back to where the data do not support a fit).
    seed : int
        Seed of the augmentation and the training.
    epochs : int or None
        Training epochs (None: the recipe's default).
    model : KoopmanModel, optional
        The unfitted Koopman model to train instead of the recipe's default.
    augment : AugmentConfig, optional
        The local-frame augmentation instead of the recipe's (with ``seed``).
    on_epoch : callable, optional
        Progress callback ``(epoch, loss)`` of training.
    allow_mismatch : bool
        Learn from data of another car or period anyway (the warnings are kept).
    source : str
        Name of the data set in messages (its file).

    Raises
    ------
    ContractError
        When the data were recorded with another car, wheelbase or period, unless ``allow_mismatch``.
    InputFileError
        For data no model should be learned from (:func:`rkmpc.learning.data.plausibility.check_learnable`).
    NotLearnedError
        For a model of the kinematic model's input (``residual``) that predicts its held-out
        windows worse than no correction at all
        (:meth:`rkmpc.learning.pipeline.TrainReport.worse_than_no_correction`).
    """
    with threadpool_limits(limits=TRAINING_THREADS, user_api="blas"):
        wheelbase = vehicle.wheelbase
        if isinstance(recipe.learner, KoopmanLearner):
            learner = recipe.learner
            config = TrainConfig(
                kind=recipe.kind,
                augment=augment if augment is not None else learner.augment(seed),
                model=model if model is not None else learner.default_model(seed, epochs),
                dt=made_for.dt,
            )
            fitted, report = train_model(
                data,
                wheelbase,
                config,
                on_epoch=on_epoch,
                vehicle=made_for.vehicle,
                allow_mismatch=allow_mismatch,
                source=source,
            )
            worse = report.worse_than_no_correction()
            if worse is not None:
                raise NotLearnedError(
                    source,
                    recipe.kind,
                    f"{worse}: its correction would steer the car worse than none (laps that end in a "
                    "spin teach a correction that diverges over the horizon)",
                )
            warned = tuple(fitted.metadata_["contract_warnings"])
            return Learned(
                recipe=recipe, model=fitted, report=report, warnings=warned, metadata=fitted.metadata_
            )
        warned = data.contract.check(made_for, source=source, made="recorded", allow_mismatch=allow_mismatch)
        check_learnable(data, wheelbase, source)
        ident = identify(data, vehicle)
        if recipe.learner.tyres:
            ident = replace(ident, tyres=identify_tyres(data, vehicle, ident))
        contract = replace(data.contract, dt=data.dt, wheelbase=wheelbase, recorded=True)
        metadata = {
            "data_hash": data.content_hash(),
            "data_metadata": data.metadata,
            CONTRACT_KEY: contract.to_json(),
            "contract_warnings": list(warned),
        }
        return Learned(
            recipe=recipe,
            model=ident,
            report=None,
            warnings=(*warned, *ident.every_warning),
            metadata=metadata,
        )


def save_learned(learned: Learned, path: str | Path) -> None:
    """Write the model to its kind's file (an archive, or JSON for an identified model)."""
    if isinstance(learned.model, KoopmanModel):
        learned.model.save(path, metadata=learned.metadata)
    else:
        save_identified(learned.model, path, learned.metadata)
