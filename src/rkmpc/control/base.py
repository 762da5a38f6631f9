"""The controller interface: observation in, command out.

Any simulator, or a real car, can drive a :class:`Controller`: build it from a
reference and vehicle parameters, call :meth:`Controller.reset` before a run
and :meth:`Controller.step` once per control period.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from time import perf_counter

import numpy as np

#: Names of the columns of :meth:`Observation.as_array`.
OBSERVATION_FIELDS: tuple[str, ...] = (
    "x",
    "y",
    "yaw",
    "speed",
    "yaw_rate",
    "slip_angle",
    "steer_angle",
)


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
    """

    x: float
    y: float
    yaw: float
    speed: float
    yaw_rate: float = math.nan
    slip_angle: float = math.nan
    steer_angle: float = math.nan
    time: float = 0.0

    def as_array(self) -> np.ndarray:
        """``[x, y, yaw, speed, yaw_rate, slip_angle, steer_angle]`` as a float array."""
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


@dataclass
class StepInfo:
    """Diagnostics of the last :meth:`Controller.step`.

    Parameters
    ----------
    status : str
        ``"ok"``, or ``"fallback"`` when the solver failed and a fall-back
        command was used.
    solve_time_s : float
        Wall time of the step (s), measured by the controller itself.
    message : str
        Solver message on failure, empty otherwise.
    """

    status: str = "ok"
    solve_time_s: float = 0.0
    message: str = ""


class Controller(ABC):
    """Base class of all controllers.

    Subclasses implement :meth:`_reset` and :meth:`_step`; this class times
    every step and counts the fall-backs.
    """

    #: Registry name of the controller (``"lmpc"``, ``"pp"``, ...).
    name: str = "controller"

    def __init__(self) -> None:
        self.info = StepInfo()
        self.fallback_count = 0
        self.step_count = 0

    def reset(self) -> None:
        """Forget all internal state (warm starts, previous inputs, counters)."""
        self.info = StepInfo()
        self.fallback_count = 0
        self.step_count = 0
        self._reset()

    def step(self, observation: Observation) -> Command:
        """Compute the command for this control period.

        Parameters
        ----------
        observation : Observation
            The car's current observation.

        Returns
        -------
        Command
            Speed (m/s) and front wheel angle (rad) set-points.
        """
        t0 = perf_counter()
        command, status, message = self._step(observation)
        elapsed = perf_counter() - t0
        self.step_count += 1
        if status != "ok":
            self.fallback_count += 1
        self.info = StepInfo(status=status, solve_time_s=elapsed, message=message)
        return command

    @abstractmethod
    def _reset(self) -> None:
        """Reset subclass state."""

    @abstractmethod
    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        """Return ``(command, status, message)``; status is ``"ok"`` or ``"fallback"``."""
