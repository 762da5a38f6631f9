"""Recipes: one record per learned controller, the single place that defines how its model is made.

A :class:`Recipe` names the controller that drives with the model, the model
kind written into the model file, the learner (a Koopman model or a physical
identification), the state features (:mod:`rkmpc.learning.features`, the same
map feeds the controller on the car), the model's input and output, where the
data come from (laps of the track or random excitation of the car) and the
default training. The controller registry, ``rkmpc train --kind``, the
experiments and the studies all read these records; adding a learned
controller means writing one recipe (and the controller class).
"""

from __future__ import annotations

from dataclasses import dataclass

from rkmpc.core.errors import ParameterError
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.features import KMPC_STATE, PAPER_STATE, RESIDUAL_STATE, FeatureMap
from rkmpc.learning.koopman.lifting import MLPLifting
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.koopman.settings import MLPTraining

__all__ = ["LEARNERS", "RECIPES", "Recipe", "model_kinds", "recipe_for", "recipe_of_kind"]

#: How a recipe's model is learned.
LEARNERS = ("koopman", "identification")
_INPUTS = ("command", "control_residual")
_OUTPUTS = ("state", "nominal_input", "physical")
_DATA = ("track", "excitation")


@dataclass(frozen=True)
class Recipe:
    """How the model of one learned controller is made.

    Parameters
    ----------
    controller : str
        Registry name of the controller that drives with the model.
    kind : str
        Model kind, written into the model file and checked when it is loaded.
    learner : str
        ``"koopman"`` (a :class:`~rkmpc.learning.koopman.model.KoopmanModel`) or
        ``"identification"`` (:func:`rkmpc.learning.identification.identify`).
    state : FeatureMap or None
        State features of a Koopman model (None for an identification).
    model_input : str
        ``"command"`` (the command applied) or ``"control_residual"`` (``dU = U - U_p``).
    output : str
        ``"state"`` (the model predicts its state), ``"nominal_input"`` (the input ``U_p`` the
        kinematic model needs, ``y = C z + D u``) or ``"physical"`` (identified parameters).
    data : str
        ``"track"`` (LMPC laps of the track) or ``"excitation"`` (random excitation in open space).
    augment_ratio : float
        Conversion ratio of the local-frame augmentation (the fraction of samples that start a window).
    description : str
        One line for tables and ``--help``.
    """

    controller: str
    kind: str
    learner: str
    state: FeatureMap | None
    model_input: str
    output: str
    data: str
    augment_ratio: float
    description: str

    def __post_init__(self) -> None:
        checks = (
            ("learner", self.learner, LEARNERS),
            ("model_input", self.model_input, _INPUTS),
            ("output", self.output, _OUTPUTS),
            ("data", self.data, _DATA),
        )
        for name, value, allowed in checks:
            if value not in allowed:
                raise ParameterError(
                    f"Recipe({self.controller!r}).{name} must be one of {allowed}, got {value!r}"
                )
        if (self.learner == "koopman") != (self.state is not None):
            raise ParameterError(
                f"Recipe({self.controller!r}): a Koopman model needs state features, only it"
            )
        if not 0.0 < self.augment_ratio <= 1.0:
            raise ParameterError(f"Recipe({self.controller!r}).augment_ratio must be in (0, 1]")

    def augment(self, seed: int) -> AugmentConfig:
        """The local-frame augmentation of this recipe (ratio, default window length) with ``seed``."""
        return AugmentConfig(ratio=self.augment_ratio, seed=seed)

    def default_model(self, seed: int, epochs: int | None = None) -> KoopmanModel:
        """The unfitted Koopman model trained by default: a 16-feature network, 100 epochs (or ``epochs``).

        A fixed number of epochs and no wall-clock budget: the model does not depend on the machine's load.
        """
        if self.learner != "koopman":
            raise ParameterError(f"the {self.kind!r} model of {self.controller!r} is identified, not trained")
        training = MLPTraining(epochs=100 if epochs is None else epochs, seed=seed)
        return KoopmanModel(MLPLifting(n_lift=16, hidden=(64, 64), training=training))


#: The recipes of the learned controllers, in table order.
RECIPES: tuple[Recipe, ...] = (
    Recipe(
        controller="lmpc-id",
        kind="identified",
        learner="identification",
        state=None,
        model_input="command",
        output="physical",
        data="track",
        augment_ratio=0.3,
        description="servo time constant and understeer gradient, least squares",
    ),
    Recipe(
        controller="rkmpc-paper",
        kind="paper",
        learner="koopman",
        state=PAPER_STATE,
        model_input="control_residual",
        output="state",
        data="track",
        augment_ratio=0.3,
        description="local x, y, yaw (input: control residual dU)",
    ),
    Recipe(
        controller="rkmpc",
        kind="residual",
        learner="koopman",
        state=RESIDUAL_STATE,
        model_input="command",
        output="nominal_input",
        data="track",
        augment_ratio=0.3,
        description="speed, yaw_rate, steer_angle -> U_p (input: command)",
    ),
    Recipe(
        controller="kmpc",
        kind="koopman",
        learner="koopman",
        state=KMPC_STATE,
        model_input="command",
        output="state",
        data="excitation",
        # The excitation data are long and varied, so a few window origins per trajectory suffice.
        augment_ratio=0.05,
        description="local x, y, yaw, speed, yaw_rate, steer_angle (input: command)",
    ),
)

_BY_CONTROLLER = {r.controller: r for r in RECIPES}
_BY_KIND = {r.kind: r for r in RECIPES}


def recipe_for(controller: str) -> Recipe | None:
    """The recipe of a learned controller, or None for a controller that learns nothing."""
    return _BY_CONTROLLER.get(controller)


def recipe_of_kind(kind: str) -> Recipe:
    """The recipe whose model is of ``kind``; ParameterError naming the known kinds otherwise."""
    try:
        return _BY_KIND[kind]
    except KeyError:
        raise ParameterError(f"unknown model kind {kind!r}; known: {sorted(_BY_KIND)}") from None


def model_kinds() -> list[str]:
    """Every model kind, in table order."""
    return [r.kind for r in RECIPES]
