"""Recipes: one record per learned controller, the single place that defines how its model is made.

A :class:`Recipe` names the controller that drives with the model, the model
kind written into the model file, the learner (a :class:`KoopmanLearner` with its
state features (:mod:`rkmpc.learning.features`, the same map feeds the controller on
the car), input, output and augmentation, or an :class:`IdentificationLearner`) and
where the data come from (laps of the track or random excitation of the car). How a
model is then made from data is decided in one place, :mod:`rkmpc.learning.learn`. The controller
registry, ``rkmpc train --kind``, the
experiments and the studies all read these records; adding a learned
controller means writing one recipe (and the controller class).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from rkmpc.core.errors import ParameterError
from rkmpc.core.registry import Registry
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.features import KMPC_STATE, PAPER_STATE, RESIDUAL_STATE, FeatureMap
from rkmpc.learning.koopman.lifting import MLPLifting
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.koopman.settings import MLPTraining

__all__ = [
    "RECIPES",
    "DataSource",
    "IdentificationLearner",
    "KoopmanLearner",
    "ModelInput",
    "ModelOutput",
    "Recipe",
    "model_kinds",
    "recipe_for",
    "recipe_of_kind",
    "track_learners",
]


class ModelInput(StrEnum):
    """What drives a Koopman model: the command applied, or the control residual ``dU = U - U_p``."""

    COMMAND = "command"
    CONTROL_RESIDUAL = "control_residual"


class ModelOutput(StrEnum):
    """What a Koopman model outputs: its state, or the input ``U_p`` the kinematic model needs."""

    STATE = "state"
    NOMINAL_INPUT = "nominal_input"


class DataSource(StrEnum):
    """Where a recipe's data come from: LMPC laps of the track, or random excitation of the car."""

    TRACK = "track"
    EXCITATION = "excitation"


@dataclass(frozen=True)
class KoopmanLearner:
    """A lifted linear (Koopman) model trained on windows of the data (:mod:`rkmpc.learning.pipeline`).

    Parameters
    ----------
    state : FeatureMap
        The model's state features (the same map feeds the controller on the car).
    model_input : ModelInput
        The command applied, or the control residual.
    output : ModelOutput
        The model's own state, or the nominal input ``U_p`` (``y = C z + D u``).
    augment_ratio : float
        Conversion ratio of the local-frame augmentation (the fraction of samples that start a
        window), in (0, 1].
    """

    state: FeatureMap
    model_input: ModelInput
    output: ModelOutput
    augment_ratio: float

    def __post_init__(self) -> None:
        if not isinstance(self.state, FeatureMap):
            raise ParameterError(f"KoopmanLearner.state must be a FeatureMap, got {self.state!r}")
        object.__setattr__(self, "model_input", ModelInput(self.model_input))
        object.__setattr__(self, "output", ModelOutput(self.output))
        if not 0.0 < self.augment_ratio <= 1.0:
            raise ParameterError(
                f"KoopmanLearner.augment_ratio must be in (0, 1], got {self.augment_ratio!r}"
            )

    #: Trained models depend only on their data and settings: they are cached by content hash.
    cacheable = True

    def augment(self, seed: int) -> AugmentConfig:
        """The local-frame augmentation (ratio, default window length) with ``seed``."""
        return AugmentConfig(ratio=self.augment_ratio, seed=seed)

    def default_model(self, seed: int, epochs: int | None = None) -> KoopmanModel:
        """The unfitted model trained by default: a 16-feature network, 100 epochs (or ``epochs``).

        A fixed number of epochs and no wall-clock budget: the model does not depend on the machine's load.
        """
        training = MLPTraining(epochs=100 if epochs is None else epochs, seed=seed)
        return KoopmanModel(MLPLifting(n_lift=16, hidden=(64, 64), training=training))


@dataclass(frozen=True)
class IdentificationLearner:
    """A few physical parameters identified by least squares (:mod:`rkmpc.learning.identification`).

    Parameters
    ----------
    tyres : bool
        Identify the tyre curves too (:mod:`rkmpc.learning.tyre_fit`), for a dynamic model.
    """

    tyres: bool = False

    #: Identification is quick and has no settings worth caching under.
    cacheable = False

    def __post_init__(self) -> None:
        if not isinstance(self.tyres, bool):
            raise ParameterError(f"IdentificationLearner.tyres must be a bool, got {self.tyres!r}")


Learner = KoopmanLearner | IdentificationLearner


@dataclass(frozen=True)
class Recipe:
    """How the model of one learned controller is made.

    Parameters
    ----------
    controller : str
        Registry name of the controller that drives with the model.
    kind : str
        Model kind, written into the model file and checked when it is loaded.
    learner : KoopmanLearner or IdentificationLearner
        How the model is learned.
    data : DataSource
        Where the data come from.
    description : str
        One line for tables and ``--help``.
    """

    controller: str
    kind: str
    learner: Learner
    data: DataSource
    description: str

    def __post_init__(self) -> None:
        if not isinstance(self.learner, KoopmanLearner | IdentificationLearner):
            raise ParameterError(f"Recipe({self.controller!r}).learner must be a learner: {self.learner!r}")
        object.__setattr__(self, "data", DataSource(self.data))

    @property
    def state(self) -> FeatureMap | None:
        """The state features of a Koopman model (None for an identification)."""
        return self.learner.state if isinstance(self.learner, KoopmanLearner) else None

    def koopman(self) -> KoopmanLearner:
        """The Koopman learner; ParameterError for an identified model."""
        if not isinstance(self.learner, KoopmanLearner):
            raise ParameterError(f"the {self.kind!r} model of {self.controller!r} is identified, not trained")
        return self.learner


#: The recipes of the learned controllers, in table order.
RECIPES: tuple[Recipe, ...] = (
    Recipe(
        controller="lmpc-id",
        kind="identified",
        learner=IdentificationLearner(),
        data=DataSource.TRACK,
        description="servo time constant and understeer gradient, least squares",
    ),
    Recipe(
        controller="nmpc-id",
        kind="identified-tyres",
        learner=IdentificationLearner(tyres=True),
        data=DataSource.TRACK,
        description="servo, understeer and tyre curves (stiffness, Pacejka), chosen on held-out blocks",
    ),
    Recipe(
        controller="rkmpc-paper",
        kind="paper",
        learner=KoopmanLearner(PAPER_STATE, ModelInput.CONTROL_RESIDUAL, ModelOutput.STATE, 0.3),
        data=DataSource.TRACK,
        description="local x, y, yaw (input: control residual dU)",
    ),
    Recipe(
        controller="rkmpc",
        kind="residual",
        learner=KoopmanLearner(RESIDUAL_STATE, ModelInput.COMMAND, ModelOutput.NOMINAL_INPUT, 0.3),
        data=DataSource.TRACK,
        description="speed, yaw_rate, steer_angle -> U_p (input: command)",
    ),
    Recipe(
        controller="kmpc",
        kind="koopman",
        # The excitation data are long and varied, so a few window origins per trajectory suffice.
        learner=KoopmanLearner(KMPC_STATE, ModelInput.COMMAND, ModelOutput.STATE, 0.05),
        data=DataSource.EXCITATION,
        description="local x, y, yaw, speed, yaw_rate, steer_angle (input: command)",
    ),
)

_BY_CONTROLLER: Registry[Recipe] = Registry("learned controller", {r.controller: r for r in RECIPES})
_BY_KIND: Registry[Recipe] = Registry("model kind", {r.kind: r for r in RECIPES})


def recipe_for(controller: str) -> Recipe | None:
    """The recipe of a learned controller, or None for a controller that learns nothing."""
    return _BY_CONTROLLER[controller] if controller in _BY_CONTROLLER else None


def recipe_of_kind(kind: str) -> Recipe:
    """The recipe whose model is of ``kind``; UnknownNameError naming the known kinds otherwise."""
    return _BY_KIND[kind]


def model_kinds() -> list[str]:
    """Every model kind, in table order."""
    return [r.kind for r in RECIPES]


def track_learners() -> list[str]:
    """The controllers whose models learn from laps of the track (``DataSource.TRACK``), in table order."""
    return [r.controller for r in RECIPES if r.data is DataSource.TRACK]
