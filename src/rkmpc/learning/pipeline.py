"""From on-track data to a saved model: the three learned models of the project.

``residual`` (default RKMPC): features ``[speed, yaw_rate, steer_angle]``, input
the applied command, output the nominal kinematic input ``U_p`` of each
transition (:func:`rkmpc.learning.residuals.control_residuals`).

``paper`` (literal RKMPC): the pose in the local frame of each augmentation
window, input the control residual ``dU``.

``koopman`` (KMPC): ``[x, y, yaw]`` in the window's frame plus speed, yaw rate
and wheel angle, input the command; trained on random-excitation data.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rkmpc import __version__
from rkmpc.errors import ParameterError
from rkmpc.learning.augmentation import AugmentConfig, LocalWindows, local_frame_windows
from rkmpc.learning.dataset import TransitionDataset
from rkmpc.learning.koopman import KoopmanModel
from rkmpc.learning.residuals import control_residuals

#: Observation columns: x, y, yaw, speed, yaw_rate, slip_angle, steer_angle.
_POSE = [0, 1, 2]
_RESIDUAL = [3, 4, 6]
_KOOPMAN = [0, 1, 2, 3, 4, 6]

#: Model kinds and what their state features are.
MODEL_KINDS = {
    "residual": "speed, yaw_rate, steer_angle -> U_p (input: command)",
    "paper": "local x, y, yaw (input: control residual dU)",
    "koopman": "local x, y, yaw, speed, yaw_rate, steer_angle (input: command)",
}


@dataclass(frozen=True)
class TrainConfig:
    """How a model is trained.

    Parameters
    ----------
    kind : str
        One of :data:`MODEL_KINDS`.
    augment : AugmentConfig
        Local-frame windows (ratio, N_p, seed).
    model : dict
        Keyword arguments of :class:`rkmpc.learning.koopman.KoopmanModel`.
    holdout : float
        Fraction of windows (the latest in time) kept out of training for the
        multi-step error report.
    """

    kind: str = "residual"
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    model: dict[str, Any] = field(default_factory=dict)
    holdout: float = 0.2

    def __post_init__(self) -> None:
        if self.kind not in MODEL_KINDS:
            raise ParameterError(f"TrainConfig.kind must be one of {sorted(MODEL_KINDS)}, got {self.kind!r}")
        if not 0.0 <= self.holdout < 1.0:
            raise ParameterError(f"TrainConfig.holdout must be in [0, 1), got {self.holdout}")


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
        Training wall time (s).
    multi_step_error : list of float
        Held-out mean prediction error per horizon step (units of the
        model's output: m for pose models, m/s and rad combined for ``residual``).
    """

    raw_count: int
    augmented_count: int
    train_windows: int
    holdout_windows: int
    fit_time_s: float
    multi_step_error: list[float]


def _window_arrays(windows: LocalWindows, columns: list[int], inputs: np.ndarray) -> tuple[np.ndarray, ...]:
    """(Xw (M, Np+1, nx), Uw (M, Np, nu)) from windows."""
    states = np.concatenate([windows.obs[:, :, columns], windows.next_obs[:, -1:, columns]], axis=1)
    return states, inputs


def train_model(
    data: TransitionDataset,
    wheelbase: float,
    config: TrainConfig | None = None,
    *,
    on_epoch: Callable[[int, float], None] | None = None,
) -> tuple[KoopmanModel, TrainReport]:
    """Train one model of ``config.kind`` on ``data``.

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

    Returns
    -------
    model : KoopmanModel
        The fitted model; its metadata is set for saving.
    report : TrainReport
    """
    cfg = config if config is not None else TrainConfig()
    windows = local_frame_windows(data, cfg.augment)
    idx = windows.indices
    n_hold = round(cfg.holdout * windows.n_windows) if windows.n_windows > 4 else 0
    split = windows.n_windows - n_hold
    Y = None
    if cfg.kind == "residual":
        labels = control_residuals(data, wheelbase)
        Xw, Uw = _window_arrays(windows, _RESIDUAL, windows.command)
        Yw = labels.nominal[idx]
    elif cfg.kind == "paper":
        labels = control_residuals(data, wheelbase)
        Xw, Uw = _window_arrays(windows, _POSE, labels.delta[idx])
        Yw = None
    else:
        Xw, Uw = _window_arrays(windows, _KOOPMAN, windows.command)
        Yw = None
    train = slice(0, split)
    X = Xw[train, :-1].reshape(-1, Xw.shape[-1])
    X_next = Xw[train, 1:].reshape(-1, Xw.shape[-1])
    U = Uw[train].reshape(-1, Uw.shape[-1])
    if Yw is not None:
        Y = Yw[train].reshape(-1, Yw.shape[-1])
    model = KoopmanModel(**cfg.model)
    t0 = time.perf_counter()
    model.fit(X, U, X_next, Y=Y, windows=(Xw[train], Uw[train]), on_epoch=on_epoch)
    fit_time = time.perf_counter() - t0
    if n_hold:
        hold = slice(split, None)
        err = model.multi_step_error(Xw[hold], Uw[hold], None if Yw is None else Yw[hold])
        multi = [float(e) for e in err]
    else:
        multi = []
    report = TrainReport(
        raw_count=len(data),
        augmented_count=windows.augmented_count,
        train_windows=split,
        holdout_windows=n_hold,
        fit_time_s=fit_time,
        multi_step_error=multi,
    )
    model.metadata_ = {
        "kind": cfg.kind,
        "features": MODEL_KINDS[cfg.kind],
        "data_hash": data.content_hash(),
        "data_metadata": data.metadata,
        "augment": asdict(cfg.augment),
        "wheelbase": wheelbase,
        "rkmpc_version": __version__,
        "report": asdict(report),
    }
    return model, report


def default_model_options(kind: str, *, seed: int = 0) -> dict[str, Any]:
    """The :class:`KoopmanModel` settings used for each model kind by default."""
    if kind not in MODEL_KINDS:
        raise ParameterError(f"unknown model kind {kind!r}; known: {sorted(MODEL_KINDS)}")
    # A fixed number of epochs, no wall-clock budget: the model must not depend on the machine's load.
    return {
        "lifting": "mlp",
        "n_lift": 16,
        "hidden": (64, 64),
        "seed": seed,
        "epochs": 100,
        "max_seconds": None,
    }
