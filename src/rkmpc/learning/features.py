"""Named feature maps: the one definition of what a learned model sees, in training and on the car.

A :class:`FeatureMap` names the observation fields a model takes as its state,
in order. Training applies it to observation arrays (:meth:`FeatureMap.of_array`,
the windows of :mod:`rkmpc.learning.data.augmentation`, whose poses are in the
frame of each window's first sample); a controller applies it to the live
:class:`~rkmpc.core.observation.Observation` (:meth:`FeatureMap.of_observation`),
where the car sits at the origin of its own frame. Both read the same fields in
the same order, so a model can never be fed other inputs than it was trained on
(``tests/learning/test_features.py`` checks it bit for bit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS, Observation

__all__ = [
    "HISTORY_FIELDS",
    "KMPC_STATE",
    "PAPER_STATE",
    "POSE_FIELDS",
    "RESIDUAL_STATE",
    "FeatureMap",
    "previous_commands",
]

#: Fields of the pose; a feature map takes them in the car's own frame (zero on the car).
POSE_FIELDS = ("x", "y", "yaw")

#: The command applied at the previous step, ``[speed (m/s), steer (rad)]``: what a delayed
#: actuator is still acting on during this step. Not part of an observation: the controller
#: passes the command it sent, training the command recorded before each transition.
HISTORY_FIELDS = ("previous_speed_command", "previous_steer_command")

_ALL_FIELDS = (*OBSERVATION_FIELDS, *HISTORY_FIELDS)


@dataclass(frozen=True)
class FeatureMap:
    """Observation fields a model takes as its state, in order.

    Parameters
    ----------
    names : tuple of str
        Fields of :data:`~rkmpc.core.observation.OBSERVATION_FIELDS`, without repeats.
        Pose fields (``x``, ``y``, ``yaw``) are meant in the frame of the car at the
        start of the prediction: on the car they are 0.

    Raises
    ------
    ParameterError
        For an unknown or repeated field.
    """

    names: tuple[str, ...]

    def __post_init__(self) -> None:
        names = tuple(self.names)
        unknown = [n for n in names if n not in _ALL_FIELDS]
        if unknown or not names or len(set(names)) != len(names):
            raise ParameterError(
                f"FeatureMap.names must be distinct fields of {_ALL_FIELDS}, got {self.names!r}"
            )
        object.__setattr__(self, "names", names)

    @property
    def uses_history(self) -> bool:
        """Whether the map takes the previous command (:data:`HISTORY_FIELDS`)."""
        return any(n in HISTORY_FIELDS for n in self.names)

    @property
    def size(self) -> int:
        """Number of features (``nx`` of the model)."""
        return len(self.names)

    @property
    def columns(self) -> list[int]:
        """Columns of the features in an observation array followed by the previous command (7 + 2)."""
        return [_ALL_FIELDS.index(n) for n in self.names]

    def _check_history(self, previous: np.ndarray | None) -> None:
        if self.uses_history and previous is None:
            raise ParameterError(f"the features {self.describe()} need the previous command")

    def of_array(self, obs: np.ndarray, previous_command: np.ndarray | None = None) -> np.ndarray:
        """Features of observation rows, shape (..., 7) -> (..., size); poses as given (a local frame).

        ``previous_command`` (shape (..., 2)) is the command applied before each row; needed
        only when the map :attr:`uses_history`.
        """
        self._check_history(previous_command)
        if not self.uses_history:
            return obs[..., self.columns]
        return np.concatenate([obs, np.asarray(previous_command, dtype=float)], axis=-1)[..., self.columns]

    def of_observation(
        self, observation: Observation, previous_command: np.ndarray | None = None
    ) -> np.ndarray:
        """Features of a live observation, shape (size,): the pose is the car's own origin (0).

        ``previous_command`` is the command the controller sent at the previous step (shape (2,));
        needed only when the map :attr:`uses_history`.
        """
        self._check_history(previous_command)
        values = []
        for n in self.names:
            if n in HISTORY_FIELDS:
                values.append(float(np.asarray(previous_command)[HISTORY_FIELDS.index(n)]))
            else:
                values.append(0.0 if n in POSE_FIELDS else getattr(observation, n))
        return np.array(values)

    def describe(self) -> str:
        """The names, comma-separated (for result files and messages)."""
        return ", ".join(self.names)


def previous_commands(command: np.ndarray, episode: np.ndarray) -> np.ndarray:
    """The command applied before each transition, shape (N, 2).

    Within an episode it is the previous row's command; the first transition of an episode
    takes its own (the car is assumed to have held it).
    """
    command = np.asarray(command, dtype=float)
    previous = command.copy()
    if len(command) > 1:
        same = np.asarray(episode)[1:] == np.asarray(episode)[:-1]
        previous[1:][same] = command[:-1][same]
    return previous


#: ``rkmpc``: speed, yaw rate and wheel angle, and the command sent one step before (the pose does
#: not enter the residual; the previous command is what a delayed actuator still acts on).
RESIDUAL_STATE = FeatureMap(("speed", "yaw_rate", "steer_angle", *HISTORY_FIELDS))
#: ``rkmpc-paper``: the pose in the car's frame.
PAPER_STATE = FeatureMap(POSE_FIELDS)
#: ``kmpc``: the pose in the car's frame, then speed, yaw rate and wheel angle.
KMPC_STATE = FeatureMap((*POSE_FIELDS, "speed", "yaw_rate", "steer_angle"))
