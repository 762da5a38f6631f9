"""Physical identification from on-track data: the steering servo and the understeer gradient.

This is what a skeptical engineer identifies from the same laps before reaching
for a neural network: how the front wheel follows the steering command, and
how much more wheel angle than the kinematic one the car needs in a corner.

Two ways, one choice:

* **From the yaw rate** (:mod:`rkmpc.learning.yaw_fit`), what a real car allows: it
  has no steering-angle sensor, but its yaw rate answers the commands through the
  wheel. Servo and ``K`` are fitted together to ``r = v tan(delta) / (L + K v^2)``
  with the wheel run from the commands.
* **From a measured wheel angle** (:mod:`rkmpc.learning.servo_fit`), when the data
  have one: the servo fitted one step ahead on the wheel angle, ``K`` on the yaw
  rate given the measured wheel.

Either way the structure (servo structure, ``K`` or not) is chosen by how well it
predicts data it was not fitted on (time-blocked cross-validation,
:mod:`rkmpc.learning.heldout`), never by its in-sample fit, against the car's
nominal model (its data-sheet servo, ``K = 0``) on the same blocks. A model that
does not predict clearly better than the nominal one is the nominal one, marked
``status = "nominal"`` with the reason, and an
:class:`~rkmpc.core.errors.IdentificationWarning` says so; so does every other
fallback or bound (:attr:`IdentifiedModel.warnings`).

The understeer model lives in :mod:`rkmpc.learning.understeer`, the servo's in
:mod:`rkmpc.learning.servo_model`, the model record in
:mod:`rkmpc.learning.identified_model`; their names used elsewhere are
re-exported here.
"""

from __future__ import annotations

import warnings
from typing import Protocol

import numpy as np

from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.learning.heldout import DEFAULT_FOLDS, GAP_SECONDS, MIN_BLOCK, time_blocks
from rkmpc.learning.identified_model import (
    RATE_LIMIT_RANGE,
    SERVO_STRUCTURE_NAMES,
    TIME_CONSTANT_RANGE,
    IdentifiedModel,
)
from rkmpc.learning.model_choice import IdentificationData, from_wheel, from_yaw, nominal_model
from rkmpc.learning.servo_model import history_depth, vehicle_servo_parameters
from rkmpc.learning.understeer import (
    UNDERSTEER_RANGE,
    effective_wheelbase,
    gradient_bounds,
    steady_state_steer,
    understeer_excess,
    yaw_rate_of,
)
from rkmpc.learning.yaw_fit import ServoInput, YawTarget
from rkmpc.vehicle.params import VehicleParams

__all__ = [
    "IDENTIFICATION_SOURCES",
    "MIN_TRANSITIONS",
    "RATE_LIMIT_RANGE",
    "SERVO_STRUCTURE_NAMES",
    "TIME_CONSTANT_RANGE",
    "UNDERSTEER_RANGE",
    "IdentifiedModel",
    "command_history",
    "effective_wheelbase",
    "identify",
    "predicted_yaw_rate",
    "steady_state_steer",
    "understeer_excess",
    "wheel_from_commands",
]

#: Columns of the observation arrays.
_SPEED, _YAW_RATE, _STEER = (OBSERVATION_FIELDS.index(n) for n in ("speed", "yaw_rate", "steer_angle"))
#: Transitions each fit needs at least.
MIN_TRANSITIONS = 20
#: ``auto``: the measured wheel angle when the data have one, else the yaw rate; or either, forced.
IDENTIFICATION_SOURCES = ("auto", "steer_angle", "yaw_rate")


class _Transitions(Protocol):
    @property
    def obs(self) -> np.ndarray: ...
    @property
    def command(self) -> np.ndarray: ...
    @property
    def next_obs(self) -> np.ndarray: ...
    @property
    def dt(self) -> float: ...
    @property
    def episode(self) -> np.ndarray: ...


def identify(
    data: _Transitions,
    vehicle: VehicleParams,
    *,
    min_speed: float = 1.0,
    folds: int = DEFAULT_FOLDS,
    source: str = "auto",
) -> IdentifiedModel:
    """Identify the steering servo and the understeer gradient of ``vehicle`` from ``data``.

    Parameters
    ----------
    data : TransitionDataset
        Transitions grouped in episodes, with the steering commands and a yaw rate (observation
        column ``yaw_rate``) or a measured wheel angle (``steer_angle``) or both.
    vehicle : VehicleParams
        The car's nominal parameters: wheelbase L (m) and the data sheet's servo (time constant,
        s; rate limit, rad/s), the nominal model every fit is compared with.
    min_speed : float
        Transitions slower than this (m/s) are left out of the yaw-rate fits (reversing, too).
    folds : int
        Time blocks of the cross-validation (>= 2; fewer when the data are short).
    source : str
        One of :data:`IDENTIFICATION_SOURCES`: what the servo is fitted on.

    Returns
    -------
    IdentifiedModel
        With ``status`` ``identified`` or ``nominal`` and the held-out figures; a warning for
        every part kept nominal or held at a bound.

    Raises
    ------
    ParameterError
        For a bad argument, or with fewer than :data:`MIN_TRANSITIONS` transitions the chosen
        ``source`` can use: a finite wheel angle before and after, or a finite yaw rate at more
        than ``min_speed`` after the first ``history_depth(dt)`` transitions of their episode (the
        wheel run from the commands starts on the episode's first one and needs that long to
        forget it).

    Notes
    -----
    The candidates, their fits and the choice are described in :mod:`rkmpc.learning.yaw_fit`,
    :mod:`rkmpc.learning.servo_fit` and :mod:`rkmpc.learning.heldout`. A final fit with a
    parameter on an implausible bound (:func:`~rkmpc.learning.servo_model.vehicle_servo_parameters`)
    is dropped and the choice made again without it.
    """
    if not is_positive_number(min_speed):
        raise ParameterError(f"identify: min_speed must be a positive number (m/s), got {min_speed!r}")
    if not is_integer(folds, 2):
        raise ParameterError(f"identify: folds must be an integer >= 2, got {folds!r}")
    if source not in IDENTIFICATION_SOURCES:
        raise ParameterError(f"identify: source must be one of {IDENTIFICATION_SOURCES}, got {source!r}")
    d = _prepare(data, vehicle, min_speed)
    wheel, yaw = int(d.wheel_ok.sum()), int(d.yaw_ok.sum())
    use_wheel = source == "steer_angle" or (source == "auto" and wheel >= MIN_TRANSITIONS)
    usable = d.wheel_ok if use_wheel else d.yaw_ok
    n = int(usable.sum())
    if n < MIN_TRANSITIONS:
        depth = d.servo.commands.shape[1] - 1
        what = (
            "a finite wheel angle before and after"
            if use_wheel
            else f"a yaw rate at more than {min_speed:g} m/s after the first {depth} of their episode"
        )
        raise ParameterError(
            f"identify: needs at least {MIN_TRANSITIONS} transitions with {what}, got {n} "
            f"({wheel} with a wheel angle, {yaw} with a yaw rate)"
        )
    blocks = time_blocks(usable, folds, max(1, round(GAP_SECONDS / data.dt)))
    if blocks is None:
        reason = (
            f"too few transitions ({n}) for two held-out blocks of {MIN_BLOCK} and fits on {MIN_BLOCK} more "
            f"beyond {GAP_SECONDS:g} s of them: no fit can be checked"
        )
        model = nominal_model(d, n, reason, fitted_on="steer_angle" if use_wheel else "yaw_rate")
    else:
        model = (from_wheel if use_wheel else from_yaw)(d, blocks)
    for note in model.warnings:
        warnings.warn(note, IdentificationWarning, stacklevel=2)
    return model


def command_history(command: np.ndarray, episode: np.ndarray, depth: int) -> np.ndarray:
    """``[u_k, u_{k-1}, ..., u_{k-depth}]`` of each transition, NaN before its episode starts.

    Parameters
    ----------
    command : numpy.ndarray
        One command per transition, shape (N,).
    episode : numpy.ndarray
        Episode id per transition, shape (N,); consecutive transitions of an episode are
        consecutive in time.
    depth : int
        Past commands wanted.

    Returns
    -------
    numpy.ndarray
        Shape (N, depth + 1).
    """
    n = len(command)
    out = np.full((n, depth + 1), np.nan)
    for j in range(min(depth, n - 1) + 1):
        column = out[j:, j]
        column[:] = command[: n - j]
        column[episode[j:] != episode[: n - j]] = np.nan
    return out


def _prepare(data: _Transitions, vehicle: VehicleParams, min_speed: float) -> IdentificationData:
    obs, nxt, cmd = np.asarray(data.obs), np.asarray(data.next_obs), np.asarray(data.command)
    episode = np.asarray(data.episode)
    steer_command = cmd[:, 1]
    history = command_history(steer_command, episode, history_depth(data.dt))
    known = np.isfinite(history).all(axis=1)
    starts = np.ones(len(episode), dtype=bool)
    starts[1:] = episode[1:] != episode[:-1]
    first = steer_command[np.maximum.accumulate(np.where(starts, np.arange(len(starts)), 0))]
    filled = np.where(np.isfinite(history), history, first[:, None])
    steer, steer_next = obs[:, _STEER], nxt[:, _STEER]
    speed, yaw_rate = nxt[:, _SPEED], nxt[:, _YAW_RATE]
    with np.errstate(invalid="ignore"):
        fast = np.isfinite(speed) & np.isfinite(yaw_rate) & (speed > min_speed)
    steering = vehicle.steering
    return IdentificationData(
        servo=ServoInput(filled, starts, np.where(np.isfinite(steer), steer, steer_command), data.dt),
        yaw=YawTarget(
            np.where(fast, speed, 0.0),
            np.where(fast, yaw_rate, 0.0),
            vehicle.wheelbase,
            gradient_bounds(vehicle.wheelbase, float(np.max(speed[fast], initial=0.0))),
        ),
        steer=steer,
        steer_next=steer_next,
        wheel_ok=np.isfinite(steer) & np.isfinite(steer_next),
        yaw_ok=known & fast,
        parameters=vehicle_servo_parameters(steering.max_rate, data.dt),
        nominal={"delay": 0.0, "time_constant": steering.time_constant, "rate_limit": steering.max_rate},
    )


def wheel_from_commands(model: IdentifiedModel, data: _Transitions, vehicle: VehicleParams) -> np.ndarray:
    """The wheel angle (rad) ``model``'s servo gives the recorded steering commands, shape (N,).

    At the end of each transition, run from each episode's first command (the wheel at rest on
    it, or on the measured wheel angle when there is one); a rate limit of None is the car's
    nominal one.
    """
    d = _prepare(data, vehicle, 1.0)
    rate = vehicle.steering.max_rate if model.servo_rate_limit is None else model.servo_rate_limit
    values = {
        "delay": np.array([model.servo_delay]),
        "time_constant": np.array([model.servo_time_constant]),
        "rate_limit": np.array([rate]),
    }
    return d.servo.wheel(values)[0]


def predicted_yaw_rate(
    model: IdentifiedModel, data: _Transitions, vehicle: VehicleParams, *, min_speed: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """The yaw rate ``model`` predicts from the commands alone, and the measured one.

    ``v tan(delta) / (L + K v^2)`` with the measured speed ``v`` and the wheel angle of
    :func:`wheel_from_commands`, on the transitions :func:`identify` fits the yaw rate on (a yaw
    rate, faster than ``min_speed``, after the first ``history_depth(dt)`` of their episode).

    Returns
    -------
    predicted, measured : numpy.ndarray
        Yaw rate at the end of those transitions (rad/s), shape (n,) each.
    """
    d = _prepare(data, vehicle, min_speed)
    wheel = wheel_from_commands(model, data, vehicle)
    pred = yaw_rate_of(np.tan(wheel), d.yaw.speed, vehicle.wheelbase, model.understeer_gradient)
    return pred[d.yaw_ok], d.yaw.yaw_rate[d.yaw_ok]
