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

__all__ = ["KMPC_STATE", "PAPER_STATE", "POSE_FIELDS", "RESIDUAL_STATE", "FeatureMap"]

#: Fields of the pose; a feature map takes them in the car's own frame (zero on the car).
POSE_FIELDS = ("x", "y", "yaw")


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
        unknown = [n for n in names if n not in OBSERVATION_FIELDS]
        if unknown or not names or len(set(names)) != len(names):
            raise ParameterError(
                f"FeatureMap.names must be distinct fields of {OBSERVATION_FIELDS}, got {self.names!r}"
            )
        object.__setattr__(self, "names", names)

    @property
    def size(self) -> int:
        """Number of features (``nx`` of the model)."""
        return len(self.names)

    @property
    def columns(self) -> list[int]:
        """Columns of the features in an observation array."""
        return [OBSERVATION_FIELDS.index(n) for n in self.names]

    def of_array(self, obs: np.ndarray) -> np.ndarray:
        """Features of observation rows, shape (..., 7) -> (..., size); poses as given (a local frame)."""
        return obs[..., self.columns]

    def of_observation(self, observation: Observation) -> np.ndarray:
        """Features of a live observation, shape (size,): the pose is the car's own origin (0)."""
        return np.array([0.0 if n in POSE_FIELDS else getattr(observation, n) for n in self.names])

    def describe(self) -> str:
        """The names, comma-separated (for result files and messages)."""
        return ", ".join(self.names)


#: ``rkmpc``: speed, yaw rate and wheel angle (the pose does not enter the residual).
RESIDUAL_STATE = FeatureMap(("speed", "yaw_rate", "steer_angle"))
#: ``rkmpc-paper``: the pose in the car's frame.
PAPER_STATE = FeatureMap(POSE_FIELDS)
#: ``kmpc``: the pose in the car's frame, then speed, yaw rate and wheel angle.
KMPC_STATE = FeatureMap((*POSE_FIELDS, "speed", "yaw_rate", "steer_angle"))
