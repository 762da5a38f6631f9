"""From data to a fitted Koopman model, following a recipe (:mod:`rkmpc.learning.recipes`).

``residual`` (default RKMPC): features :data:`~rkmpc.learning.features.RESIDUAL_STATE`, input the
applied command, output the nominal kinematic input ``U_p`` of each transition
(:func:`rkmpc.learning.data.residuals.control_residuals`).

``paper`` (literal RKMPC): the pose in the local frame of each augmentation window, input the control
residual ``dU``.

``koopman`` (KMPC): ``[x, y, yaw]`` in the window's frame plus speed, yaw rate and wheel angle, input
the command; trained on random-excitation data.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_positive_number
from rkmpc.core.versions import RKMPC_VERSION
from rkmpc.learning.contract import CONTRACT_KEY, Provenance
from rkmpc.learning.data.augmentation import AugmentConfig, LocalWindows, local_frame_windows
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.plausibility import check_learnable
from rkmpc.learning.data.residuals import control_residuals
from rkmpc.learning.features import FeatureMap, previous_commands
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.recipes import KoopmanLearner, ModelInput, ModelOutput, model_kinds, recipe_of_kind

__all__ = ["TrainConfig", "TrainReport", "train_model", "training_arrays"]


@dataclass(frozen=True)
class TrainConfig:
    """How a Koopman model is trained.

    Parameters
    ----------
    kind : str
        Model kind of a recipe whose learner is ``"koopman"`` (``residual``, ``paper``, ``koopman``).
    augment : AugmentConfig
        Local-frame windows (ratio, N_p, seed).
    model : KoopmanModel or None
        The unfitted model (lifting and training settings); None for the recipe's default with the
        augmentation's seed (:meth:`rkmpc.learning.recipes.Recipe.default_model`).
    holdout : float
        Fraction of windows (the latest in time) kept out of training for the multi-step error report.
    dt : float or None
        Control period the model is for (s); a data set recorded at another period is refused
        (:meth:`rkmpc.learning.contract.Provenance.check`). None: the data set's.
    """

    kind: str = "residual"
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    model: KoopmanModel | None = None
    holdout: float = 0.2
    dt: float | None = None

    def __post_init__(self) -> None:
        recipe = recipe_of_kind(self.kind)
        if not isinstance(recipe.learner, KoopmanLearner):
            koopman = [k for k in model_kinds() if isinstance(recipe_of_kind(k).learner, KoopmanLearner)]
            raise ParameterError(f"TrainConfig.kind must be one of {koopman}, got {self.kind!r}")
        if not 0.0 <= self.holdout < 1.0:
            raise ParameterError(f"TrainConfig.holdout must be in [0, 1), got {self.holdout}")
        if self.model is not None and not isinstance(self.model, KoopmanModel):
            raise ParameterError(f"TrainConfig.model must be a KoopmanModel or None, got {self.model!r}")
        if self.dt is not None and not is_positive_number(self.dt):
            raise ParameterError(f"TrainConfig.dt must be None or finite and > 0, got {self.dt!r}")

    def unfitted_model(self) -> KoopmanModel:
        """The model to fit: :attr:`model`, or the recipe's default."""
        if self.model is not None:
            return self.model
        return recipe_of_kind(self.kind).koopman().default_model(seed=self.augment.seed)


@dataclass(frozen=True)
class TrainReport:
    """What training did, for result files.

    Parameters
    ----------
    raw_count : int
        Transitions in the data set.
    augmented_count : int
        Local-frame transitions (windows x N_p).
    train_windows, holdout_windows : int
        Windows used for training and for the held-out report.
    fit_time_s : float
        Training wall time (s), for reports only.
    multi_step_error : list of float
        Held-out mean prediction error per horizon step (units of the model's output: m for pose
        models, m/s and rad combined for ``residual``).
    no_correction_error : list of float
        For a model of the kinematic model's input ``U_p`` driven by the command (``residual``): the
        same held-out error of no correction at all (``U_p`` taken equal to the command), per
        horizon step; empty for the other kinds or without held-out windows.
    """

    raw_count: int
    augmented_count: int
    train_windows: int
    holdout_windows: int
    fit_time_s: float
    multi_step_error: list[float]
    no_correction_error: list[float] = field(default_factory=list)

    def worse_than_no_correction(self) -> str | None:
        """Why the model predicts its held-out windows worse than no correction, or None when it does not.

        Worse means a mean error over the horizon, or an error at its last step, above no
        correction's: a model that diverges over the MPC's horizon (trained on laps that end in a
        spin, say) would steer the car by a correction that is wrong by more than its absence.
        """
        model, none = self.multi_step_error, self.no_correction_error
        if not model or len(model) != len(none):
            return None
        mean_model, mean_none = float(np.mean(model)), float(np.mean(none))
        if mean_model <= mean_none and model[-1] <= none[-1]:
            return None
        return (
            f"its held-out prediction error ({mean_model:.4g} mean over {len(model)} steps, {model[-1]:.4g} "
            f"at the last) is above no correction's ({mean_none:.4g}, {none[-1]:.4g})"
        )


def _window_states(windows: LocalWindows, state: FeatureMap, previous: np.ndarray) -> np.ndarray:
    """States ``x_0 .. x_Np`` of every window, shape (M, Np+1, nx).

    ``previous`` holds the command applied before each transition of the data set (N, 2); the
    state after a window's last step follows that step's own command.
    """
    first = state.of_array(windows.obs, previous[windows.indices])
    last = state.of_array(windows.next_obs[:, -1:], windows.command[:, -1:])
    return np.concatenate([first, last], axis=1)


def training_arrays(
    data: TransitionDataset, wheelbase: float, kind: str, windows: LocalWindows
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Window states (M, Np+1, nx), inputs (M, Np, nu) and outputs (M, Np, ny) or None of a recipe.

    The states are the recipe's :class:`~rkmpc.learning.features.FeatureMap` of the window
    observations: the same map feeds the controller on the car.
    """
    learner = recipe_of_kind(kind).koopman()
    idx = windows.indices
    residual_input = learner.model_input is ModelInput.CONTROL_RESIDUAL
    nominal_output = learner.output is ModelOutput.NOMINAL_INPUT
    labels = control_residuals(data, wheelbase) if residual_input or nominal_output else None
    Xw = _window_states(windows, learner.state, previous_commands(data.command, data.episode))
    Uw = windows.command
    if residual_input and labels is not None:
        Uw = labels.delta[idx]
    Yw = labels.nominal[idx] if nominal_output and labels is not None else None
    return Xw, Uw, Yw


def train_model(
    data: TransitionDataset,
    wheelbase: float,
    config: TrainConfig | None = None,
    *,
    on_epoch: Callable[[int, float], None] | None = None,
    vehicle: str | None = None,
    allow_mismatch: bool = False,
    source: str = "the data set",
) -> tuple[KoopmanModel, TrainReport]:
    """Train one model of ``config.kind`` on ``data``.

    The data set's contract (:attr:`TransitionDataset.contract`) is checked against the car and
    period the model is for (``vehicle``, ``wheelbase``, ``config.dt``); the model records its own
    (:data:`rkmpc.learning.contract.CONTRACT_KEY` in ``metadata_``): the car, the data's period and
    track scale, and the range of its state features.

    Parameters
    ----------
    data : TransitionDataset
        On-track (``residual``, ``paper``) or random-excitation (``koopman``) data.
    wheelbase : float
        Wheelbase of the nominal kinematic model (m).
    config : TrainConfig, optional
        Kind, augmentation and model settings.
    on_epoch : callable, optional
        Progress callback ``(epoch, loss)``.
    vehicle : str or None
        Vehicle preset the model is for (None: not checked; the data's is recorded).
    allow_mismatch : bool
        Train on data of another car or period anyway; the warnings are kept in the model's
        metadata (``contract_warnings``).
    source : str
        Name of the data set in messages (its file).

    Returns
    -------
    model : KoopmanModel
        The fitted model; its metadata is set for saving.
    report : TrainReport

    Raises
    ------
    ContractError
        When the data were recorded with another car, wheelbase or period, unless ``allow_mismatch``.
    InputFileError
        Naming ``source``, the field and the rows, for data no model should be learned from: the car
        stood still, the transitions do not match the speeds, the heading is not the direction of
        motion, or a feature is not finite (:func:`rkmpc.learning.data.plausibility.check_learnable`).
    """
    cfg = config if config is not None else TrainConfig()
    recipe = recipe_of_kind(cfg.kind)
    made_with = data.contract
    warned = made_with.check(
        Provenance(vehicle=vehicle, dt=cfg.dt, wheelbase=wheelbase),
        source=source,
        made="recorded",
        allow_mismatch=allow_mismatch,
    )
    check_learnable(data, wheelbase, source, () if recipe.state is None else recipe.state.names)
    windows = local_frame_windows(data, cfg.augment)
    n_hold = round(cfg.holdout * windows.n_windows) if windows.n_windows > 4 else 0
    split = windows.n_windows - n_hold
    Xw, Uw, Yw = training_arrays(data, wheelbase, cfg.kind, windows)
    train = slice(0, split)
    X = Xw[train, :-1].reshape(-1, Xw.shape[-1])
    X_next = Xw[train, 1:].reshape(-1, Xw.shape[-1])
    U = Uw[train].reshape(-1, Uw.shape[-1])
    Y = None if Yw is None else Yw[train].reshape(-1, Yw.shape[-1])
    model = cfg.unfitted_model()
    t0 = time.perf_counter()
    model.fit(X, U, X_next, Y=Y, windows=(Xw[train], Uw[train]), on_epoch=on_epoch)
    fit_time = time.perf_counter() - t0
    multi: list[float] = []
    none: list[float] = []
    if n_hold:
        hold = slice(split, None)
        err = model.multi_step_error(Xw[hold], Uw[hold], None if Yw is None else Yw[hold])
        multi = [float(e) for e in err]
        if Yw is not None and recipe.koopman().model_input is ModelInput.COMMAND:
            none = [float(e) for e in np.linalg.norm(Yw[hold] - Uw[hold], axis=-1).mean(axis=0)]
    report = TrainReport(
        raw_count=len(data),
        augmented_count=windows.augmented_count,
        train_windows=split,
        holdout_windows=n_hold,
        fit_time_s=fit_time,
        multi_step_error=multi,
        no_correction_error=none,
    )
    contract = Provenance(
        vehicle=made_with.vehicle if made_with.vehicle is not None else vehicle,
        plant=made_with.plant,
        dt=data.dt,
        wheelbase=wheelbase,
        scale=made_with.scale,
        features=() if recipe.state is None else recipe.state.names,
        state_min=tuple(model.x_min_),
        state_max=tuple(model.x_max_),
    )
    model.metadata_ = {
        CONTRACT_KEY: contract.to_json(),
        "contract_warnings": list(warned),
        "kind": cfg.kind,
        "features": [] if recipe.state is None else list(recipe.state.names),
        "model_input": str(recipe.koopman().model_input),
        "output": str(recipe.koopman().output),
        "data_hash": data.content_hash(),
        "data_metadata": data.metadata,
        "augment": asdict(cfg.augment),
        "wheelbase": wheelbase,
        "rkmpc_version": RKMPC_VERSION,
        "report": asdict(report),
    }
    return model, report
