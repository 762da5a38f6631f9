"""How well trained models predict recorded driving: :func:`evaluate` (``rkmpc evaluate``).

Open-loop k-step prediction: from every sample whose next ``H`` transitions lie in one episode,
each model predicts the car's pose and speed ``1..H`` steps ahead from the sample's state and the
*recorded* commands alone, and is scored against where the car really went. Every model is judged
against the nominal kinematic bicycle driven by the same commands (``kinematic``):

``kinematic``
    The paper's kinematic bicycle with the command as its input (``U = [v_cmd, delta_cmd]``).
``residual`` (rkmpc)
    The lifted model predicts the input ``U_p`` the kinematic bicycle needs (``y = C z + D u``,
    ``z+ = A z + B u``) from the state features at the start; the bicycle driven by ``U_p``. As rkmpc
    drives with it, the correction ``U_p - U`` fades toward 0 where the start's features leave the
    model's training range (:class:`~rkmpc.control.learned.trust.CorrectionTrust`).
``identified`` (lmpc-id)
    The identified servo turns the recorded steering commands into a wheel angle, and the bicycle
    turns with the identified understeer: curvature ``tan(delta) / (L + K v^2)``.
``koopman`` (kmpc)
    The lifted model predicts the pose in the car's frame and the speed itself.

Where the car's ``rkmpc`` settings hold the slip drift (``[controllers.rkmpc] slip_drift``, on in the
``f1tenth`` preset), two rows more say what ``rkmpc`` itself predicts with a residual model:

``residual+drift``
    The residual model's prediction with the start's slip angle held over the horizon: every step
    travels at that angle to the predicted heading (weighted by
    :meth:`~rkmpc.control.learned.residual_config.RKMPCConfig.slip_drift_weight`), as the residual
    QP adds it to its prediction. A start without a slip angle goes without its drift.
``kinematic+drift``
    The same drift on the kinematic model: how much of that row the drift alone makes.

Beside the models, the *exact inputs* (``exact-inputs``): the kinematic bicycle driven by the input
``U_p`` that reproduces each recorded step's travelled distance and heading change
(:func:`rkmpc.learning.data.residuals.kinematic_inverse` of the truth), i.e. what a perfect model
of the residual model's form (a correction of the kinematic model's input) would predict. What it
still misses is the sideways motion the bicycle cannot make (the centre of gravity drifting to the
inside of a turn, slip): nearly a floor for that form (a model can land marginally closer in
position only by erring in heading).

The ``paper`` model (rkmpc-paper) predicts what a *correction* ``dU`` on top of the LMPC's plan
does, which recorded driving does not contain: it cannot be evaluated here and is refused.

Where the recorded data measure the car's state (speed, yaw rate, wheel angle), the truth and each
start are the data as recorded; where they do not (a real car: no wheel angle, a localiser whose
pose jumps), both are the state estimator's smoothed estimates
(:func:`rkmpc.experiments.training.estimated_for`), the wheel angle propagated through the steering
model each model was trained with.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from rkmpc.control.learned.residual_config import RKMPCConfig
from rkmpc.control.learned.trust import CorrectionTrust
from rkmpc.core.angles import wrap_angle
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.steering import SteeringModel, wheel_angles
from rkmpc.experiments.evaluation import Evaluation, EvaluationRow, evaluation_row
from rkmpc.experiments.training import estimated_for
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.residuals import kinematic_inverse
from rkmpc.learning.features import KMPC_STATE, RESIDUAL_STATE, previous_commands
from rkmpc.learning.identification import IdentifiedModel, wheel_from_commands
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.sim.build import steering_of
from rkmpc.vehicle.params import VehicleParams

__all__ = ["DEFAULT_HORIZONS", "Evaluation", "EvaluationRow", "evaluate", "model_kind", "with_steering"]

#: Horizons of ``rkmpc evaluate`` by default (steps).
DEFAULT_HORIZONS = (1, 5, 10, 20)
#: Longest horizon (steps): 200 steps are 10 s at 20 Hz.
MAX_HORIZON = 200
_X, _Y, _YAW, _SPEED, _SLIP, _STEER = (
    OBSERVATION_FIELDS.index(n) for n in ("x", "y", "yaw", "speed", "slip_angle", "steer_angle")
)
#: The row kinds of a prediction with ``rkmpc``'s slip drift, by the kind it is added to.
DRIFT_KINDS = {"kinematic": "kinematic+drift", "residual": "residual+drift"}


def model_kind(model: object) -> str:
    """The kind of a model as its file says (``residual``, ``identified``, ``koopman``, ...)."""
    if isinstance(model, IdentifiedModel):
        return "identified"
    metadata = getattr(model, "metadata_", None)
    if isinstance(metadata, dict) and "kind" in metadata:
        return str(metadata["kind"])
    raise ParameterError(f"cannot tell the kind of the model {model!r}")


def with_steering(data: TransitionDataset, steering: SteeringModel) -> TransitionDataset:
    """``data`` with its wheel angles propagated from its commands through ``steering``, per episode."""
    obs, next_obs = data.obs.copy(), data.next_obs.copy()
    episode = np.asarray(data.episode)
    for value in np.unique(episode):
        rows = np.flatnonzero(episode == value)
        angles = wheel_angles(steering, data.dt, data.command[rows, 1])
        obs[rows, _STEER] = angles[:-1]
        next_obs[rows, _STEER] = angles[1:]
    return replace(data, obs=obs, next_obs=next_obs)


def _starts(data: TransitionDataset, horizon: int) -> np.ndarray:
    """Rows from which ``horizon`` transitions follow within one episode."""
    n = len(data)
    if n < horizon:
        return np.zeros(0, dtype=int)
    episode = np.asarray(data.episode)
    idx = np.arange(n - horizon + 1)
    return idx[episode[idx] == episode[idx + horizon - 1]]


def _arcs(
    pose: np.ndarray, speed: np.ndarray, curvature: np.ndarray, dt: float, slip: np.ndarray | None = None
) -> np.ndarray:
    """Poses (M, H, 3) after each arc of ``speed`` and ``curvature`` (M, H) from ``pose`` (M, 3).

    ``slip`` (M,): an angle (rad) at which every step of a start travels to its heading without
    turning it (the slip drift); None: along the heading.
    """
    m, h = speed.shape
    out = np.empty((m, h, 3))
    x, y, yaw = pose[:, 0].copy(), pose[:, 1].copy(), pose[:, 2].copy()
    beta = np.zeros(m) if slip is None else slip
    for k in range(h):
        distance = speed[:, k] * dt
        half = 0.5 * distance * curvature[:, k]
        small = np.abs(half) < 1e-4
        chord = np.where(small, 1.0 - half * half / 6.0, np.sin(half) / np.where(small, 1.0, half))
        x = x + distance * chord * np.cos(yaw + half + beta)
        y = y + distance * chord * np.sin(yaw + half + beta)
        yaw = yaw + 2.0 * half
        out[:, k] = np.stack([x, y, yaw], axis=1)
    return out


def _window(values: np.ndarray, starts: np.ndarray, horizon: int) -> np.ndarray:
    """``values[start + k]`` for every start and ``k < horizon``: shape (M, horizon, ...)."""
    return values[starts[:, None] + np.arange(horizon)[None, :]]


def _drift(data: TransitionDataset, starts: np.ndarray, settings: RKMPCConfig) -> np.ndarray:
    """The slip angle (rad, M) ``rkmpc``'s drift holds from each start: its weighted slip, 0 where
    the start has none."""
    obs = data.obs[starts]
    slip = np.where(np.isfinite(obs[:, _SLIP]), obs[:, _SLIP], 0.0)
    weight = [settings.slip_drift_weight(b, v) for b, v in zip(slip, obs[:, _SPEED], strict=True)]
    return slip * np.asarray(weight, dtype=float)


def _arc_inputs(
    kind: str,
    model: object,
    data: TransitionDataset,
    starts: np.ndarray,
    horizon: int,
    vehicle: VehicleParams,
    settings: RKMPCConfig,
) -> tuple[np.ndarray, np.ndarray]:
    """Speeds (m/s) and curvatures (1/m), each (M, H), of the arcs a kinematic, identified or
    residual model drives from each start.

    ``settings``: ``rkmpc``'s (the trust range of its correction).
    """
    commands = _window(data.command, starts, horizon)
    length = vehicle.wheelbase
    if kind == "kinematic":
        return commands[..., 0], np.tan(commands[..., 1]) / length
    if kind == "identified" and isinstance(model, IdentifiedModel):
        wheel = _window(wheel_from_commands(model, data, vehicle), starts, horizon)
        speed = commands[..., 0]
        return speed, np.tan(wheel) / (length + model.understeer_gradient * speed**2)
    if kind != "residual" or not isinstance(model, KoopmanModel):
        raise ParameterError(
            f"a {kind!r} model cannot be evaluated on recorded driving"
            + (
                ": it predicts what a correction dU on the LMPC's plan does, which a recording does not hold"
                if kind == "paper"
                else ""
            )
        )
    previous = previous_commands(data.command, data.episode)[starts]
    features = RESIDUAL_STATE.of_array(data.obs[starts], previous)
    z = model.lift(features)
    inputs = np.empty_like(commands)
    for k in range(horizon):
        inputs[:, k] = model.output(z, commands[:, k])
        z = model.step(z, commands[:, k])
    # As rkmpc drives with it: the correction fades toward the command where the features leave
    # the model's training range (rkmpc.control.learned.trust).
    trust = CorrectionTrust(model.A_, model.B_, model.Cx_, model.x_min_, model.x_max_, settings.trust)
    weight = trust.range_trust(features)[:, None, None]
    inputs = commands + weight * (inputs - commands)
    return inputs[..., 0], np.tan(inputs[..., 1]) / length


def _koopman_poses(
    model: KoopmanModel, data: TransitionDataset, starts: np.ndarray, horizon: int
) -> tuple[np.ndarray, np.ndarray]:
    """Poses (M, H, 3) and speeds (M, H) a ``kmpc`` model predicts from each start."""
    commands = _window(data.command, starts, horizon)
    pose0 = data.obs[starts][:, [_X, _Y, _YAW]]
    local = KMPC_STATE.of_array(data.obs[starts])
    local[:, :3] = 0.0  # the pose in the car's own frame
    states = np.stack([model.predict_states(x0, u)[1:] for x0, u in zip(local, commands, strict=True)])
    c, s = np.cos(pose0[:, 2])[:, None], np.sin(pose0[:, 2])[:, None]
    poses = np.stack(
        [
            pose0[:, :1] + c * states[..., 0] - s * states[..., 1],
            pose0[:, 1:2] + s * states[..., 0] + c * states[..., 1],
            pose0[:, 2:3] + states[..., 2],
        ],
        axis=-1,
    )
    return poses, states[..., 3]


def _exact_inputs(
    reference: TransitionDataset, starts: np.ndarray, horizon: int, wheelbase: float
) -> tuple[np.ndarray, np.ndarray]:
    """Poses and speeds of the kinematic model driven by each step's own ``U_p`` (module docstring)."""
    pose = reference.obs[:, [_X, _Y, _YAW]]
    inputs = _window(
        kinematic_inverse(pose, reference.next_obs[:, [_X, _Y, _YAW]], wheelbase, reference.dt),
        starts,
        horizon,
    )
    curvature = np.tan(inputs[..., 1]) / wheelbase
    return _arcs(pose[starts], inputs[..., 0], curvature, reference.dt), inputs[..., 0]


def _errors(
    predicted: tuple[np.ndarray, np.ndarray], truth_pose: np.ndarray, truth_speed: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position (m), heading (rad) and speed (m/s) errors (M, H) of predicted poses and speeds."""
    poses, speeds = predicted
    position = np.hypot(*(poses[..., :2] - truth_pose[..., :2]).transpose(2, 0, 1))
    heading = np.abs(wrap_angle(poses[..., 2] - truth_pose[..., 2]))
    return position, heading, np.abs(speeds - truth_speed)


def evaluate(
    data: TransitionDataset,
    models: Mapping[str, object],
    vehicle: VehicleParams,
    *,
    horizons: Sequence[int] = DEFAULT_HORIZONS,
    estimator: EstimatorConfig | None = None,
    rkmpc: RKMPCConfig | None = None,
    source: str | None = None,
) -> Evaluation:
    """Score every model's open-loop predictions of ``data`` against the kinematic model's.

    Parameters
    ----------
    data : TransitionDataset
        Recorded driving (a simulator's log, a bag, a CSV log), on one control period.
    models : mapping of str to model
        Trained models by the name to show (a file's name); kinds as :func:`model_kind` says.
    vehicle : VehicleParams
        The car's nominal parameters (wheelbase of the kinematic model, servo).
    horizons : sequence of int
        Steps ahead to score, 1 to :data:`MAX_HORIZON`.
    estimator : EstimatorConfig, optional
        The state estimator's settings, where the data need it.
    rkmpc : RKMPCConfig, optional
        The car's ``rkmpc`` settings: the trust range its correction fades out of and, where its
        slip drift is on, the ``*+drift`` rows (module docstring); default ``RKMPCConfig()``.
    source : str, optional
        Where the data came from, for the record.

    Raises
    ------
    ParameterError
        For a horizon out of range, a model that cannot be evaluated, or data too short.
    """
    steps = sorted({int(h) for h in horizons})
    if not steps or steps[0] < 1 or steps[-1] > MAX_HORIZON:
        raise ParameterError(f"horizons must be integers from 1 to {MAX_HORIZON}, got {list(horizons)}")
    horizon = steps[-1]
    settings = RKMPCConfig() if rkmpc is None else rkmpc
    if not isinstance(settings, RKMPCConfig):
        raise ParameterError(f"evaluate: rkmpc must be an RKMPCConfig, got {type(settings).__name__}")
    kinds = {name: model_kind(model) for name, model in models.items()}
    reference = estimated_for(recipe_of_kind("residual"), data, vehicle, estimator)
    estimated = reference is not data
    starts = _starts(reference, horizon)
    if starts.size == 0:
        raise ParameterError(f"no {horizon} consecutive transitions in one episode to evaluate on")
    truth_pose = _window(reference.next_obs, starts, horizon)[..., [_X, _Y, _YAW]]
    truth_speed = _window(reference.next_obs[:, _SPEED], starts, horizon)
    rows: list[EvaluationRow] = []
    entries: list[tuple[str | None, str, object]] = [(None, "kinematic", None)]
    entries += [(name, kinds[name], model) for name, model in models.items()]
    for name, kind, model in entries:
        # A model's wheel-angle feature, where the data do not measure it, as it was trained with.
        own = (
            with_steering(reference, steering_of(model, vehicle))
            if estimated and model is not None
            else reference
        )
        arcs = None
        pose0 = own.obs[starts][:, [_X, _Y, _YAW]]
        if kind == "koopman" and isinstance(model, KoopmanModel):  # it predicts poses itself
            predicted = _koopman_poses(model, own, starts, horizon)
        else:
            arcs = _arc_inputs(kind, model, own, starts, horizon, vehicle, settings)
            predicted = _arcs(pose0, *arcs, own.dt), arcs[0]
        errors = _errors(predicted, truth_pose, truth_speed)
        rows += [evaluation_row(kind, name, h, data.dt, errors, starts.size) for h in steps]
        if settings.slip_drift and kind in DRIFT_KINDS and arcs is not None:
            # The same arcs, each start's travelling at its drift's angle to the heading.
            predicted = _arcs(pose0, *arcs, own.dt, _drift(own, starts, settings)), arcs[0]
            errors = _errors(predicted, truth_pose, truth_speed)
            rows += [evaluation_row(DRIFT_KINDS[kind], name, h, data.dt, errors, starts.size) for h in steps]
    truth = "the state estimator's smoothed estimates" if estimated else "the data as recorded"
    exact = _errors(_exact_inputs(reference, starts, horizon, vehicle.wheelbase), truth_pose, truth_speed)
    return Evaluation(
        rows=rows,
        transitions=len(data),
        starts=int(starts.size),
        dt=data.dt,
        truth=truth,
        source=source,
        models={name: kinds[name] for name in models},
        exact_inputs=[evaluation_row("exact-inputs", None, h, data.dt, exact, starts.size) for h in steps],
    )
