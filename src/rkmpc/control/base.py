"""The controller interface: observation in, command out.

Any simulator, or a real car, can drive a :class:`Controller`: build it from a
reference and vehicle parameters, call :meth:`Controller.reset` before a run
and :meth:`Controller.step` once per control period.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from time import perf_counter

from rkmpc.core.observation import Command, Observation


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
    #: Control period the controller plans with (s); None for one that plans with none.
    dt: float | None = None

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

    def diagnostics(self) -> dict[str, float]:
        """Counts and figures of the run so far beyond the fall-backs (none by default)."""
        return {}

    @abstractmethod
    def _reset(self) -> None:
        """Reset subclass state."""

    @abstractmethod
    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        """Return ``(command, status, message)``; status is ``"ok"`` or ``"fallback"``."""
