"""What a car reports and what it is told: :class:`Observation` and :class:`Command`.

These two records cross every boundary of the package (plant to controller,
controller to plant, log to data set), so they and their field names live on
the ground floor. Arrays built from them are (time, variable) with the
variables in the order of :data:`OBSERVATION_FIELDS` and :data:`COMMAND_FIELDS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["COMMAND_FIELDS", "OBSERVATION_FIELDS", "Command", "Observation"]

#: Names of the columns of :meth:`Observation.as_array` (and of observation arrays).
OBSERVATION_FIELDS: tuple[str, ...] = (
    "x",
    "y",
    "yaw",
    "speed",
    "yaw_rate",
    "slip_angle",
    "steer_angle",
)

#: Names of the columns of command arrays: ``[speed (m/s), steer (rad)]``.
COMMAND_FIELDS: tuple[str, ...] = ("speed", "steer")


@dataclass(frozen=True)
class Observation:
    """What the car's localisation reports at one control instant (SI units).

    Parameters
    ----------
    x, y : float
        Position of the centre of gravity in the track frame (m).
    yaw : float
        Heading (rad), any branch; controllers wrap it themselves.
    speed : float
        Speed along the heading (m/s).
    yaw_rate : float, optional
        Yaw rate (rad/s); NaN when not measured.
    slip_angle : float, optional
        Side-slip angle at the centre of gravity (rad); NaN when not measured.
    steer_angle : float, optional
        Measured front wheel angle (rad); NaN when not measured.
    time : float, optional
        Time stamp (s).
    pose_time : float, optional
        When the pose (``x``, ``y``, ``yaw``) was measured (s, on the clock of ``time``); NaN when
        it is as current as ``time``. A localiser's pose comes late and at its own rate: a
        ``pose_time`` that has not changed since the last observation means no new pose.
    """

    x: float
    y: float
    yaw: float
    speed: float
    yaw_rate: float = math.nan
    slip_angle: float = math.nan
    steer_angle: float = math.nan
    time: float = 0.0
    pose_time: float = math.nan

    def as_array(self) -> np.ndarray:
        """``[x, y, yaw, speed, yaw_rate, slip_angle, steer_angle]`` as a float array, shape (7,)."""
        return np.array(
            [self.x, self.y, self.yaw, self.speed, self.yaw_rate, self.slip_angle, self.steer_angle]
        )


@dataclass(frozen=True)
class Command:
    """What a controller asks of the car for one control period.

    Parameters
    ----------
    speed : float
        Speed set-point (m/s).
    steer : float
        Front wheel angle set-point (rad), positive to the left.
    """

    speed: float
    steer: float
