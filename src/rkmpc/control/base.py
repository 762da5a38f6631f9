"""The controller interface: observation in, command out, never an exception.

Any simulator, or a real car, can drive a :class:`Controller`: build it from a
reference and vehicle parameters, call :meth:`Controller.reset` before a run
and :meth:`Controller.step` once per control period.

:meth:`Controller.step` is the one place that guards every controller. Before the
controller's own step it checks the observation and, for a controller that tracks a
reference, the car's distance and heading from it (:class:`AdmissibleErrors`, as
Autoware's MPC checks every cycle); after it, it checks the command. A step refused
by a check, or one in which the controller raised, answers the safe command
(:func:`stop_command`: speed 0, the wheel held where the last command put it, as the
ROS node's safety stop does) without touching the controller's state, so the next
valid observation is answered as if the refused one had never come.

Observation fields
------------------
``x``, ``y``, ``yaw``, ``speed`` must be finite (NaN or infinite: ``"invalid_input"``).
``yaw_rate``, ``slip_angle`` and ``steer_angle`` are NaN when not measured, which every
controller accepts unless it lists the field in :attr:`Controller.measured_fields`
(the Koopman MPC needs the yaw rate and the wheel angle); infinite is never valid.
"""

from __future__ import annotations

import logging
import math
from abc import ABC, abstractmethod
from collections import Counter
from dataclasses import dataclass
from time import perf_counter
from typing import TYPE_CHECKING, Any

from rkmpc.core.angles import wrap_scalar
from rkmpc.core.errors import ParameterError, raise_if_interrupted
from rkmpc.core.interrupt import check_interrupted
from rkmpc.core.observation import Command, Observation

if TYPE_CHECKING:
    from rkmpc.track.projection import Projection
    from rkmpc.track.reference import Reference
    from rkmpc.vehicle.params import VehicleParams

__all__ = [
    "OPTIONAL_FIELDS",
    "REQUIRED_FIELDS",
    "STATUSES",
    "STATUS_CODES",
    "AdmissibleErrors",
    "Controller",
    "StepInfo",
    "stop_command",
]

_LOG = logging.getLogger(__name__)

#: Every status a step can end with; all but ``"ok"`` count as a fall-back.
#:
#: ``ok`` the solver succeeded; ``fallback`` a failure the controller did not classify;
#: ``infeasible`` the solver proved its problem infeasible; ``iteration_limit`` it ran out
#: of iterations (or of a time budget a user opted into); ``numerical`` any other solver
#: failure (non-convex, cycling, restoration failed, NaN in the solver, non-finite
#: solution); ``invalid_input`` the observation was refused; ``inadmissible`` the car was
#: farther from the reference than :class:`AdmissibleErrors` allow; ``guard`` the
#: controller's own safeguard kept its baseline (the residual MPCs on non-finite features);
#: ``exception`` the controller raised; ``nonfinite_command`` it answered NaN or infinity.
STATUSES: tuple[str, ...] = (
    "ok",
    "fallback",
    "infeasible",
    "iteration_limit",
    "numerical",
    "invalid_input",
    "inadmissible",
    "guard",
    "exception",
    "nonfinite_command",
)

#: The number of each status in step logs (``ok`` 0 and ``fallback`` 1, as in older logs).
STATUS_CODES: dict[str, float] = {status: float(code) for code, status in enumerate(STATUSES)}

#: Observation fields every controller needs finite (m, m, rad, m/s).
REQUIRED_FIELDS: tuple[str, ...] = ("x", "y", "yaw", "speed")
#: Observation fields that are NaN when not measured (rad/s, rad, rad); never infinite.
OPTIONAL_FIELDS: tuple[str, ...] = ("yaw_rate", "slip_angle", "steer_angle")

#: Wheelbase (m) of Autoware's default vehicle, the scale of its admissible position error.
_AUTOWARE_WHEELBASE = 2.79


@dataclass(frozen=True)
class AdmissibleErrors:
    """How far from the reference a car may be for a controller to drive it.

    Autoware's MPC stops the car when it is more than ``admissible_position_error``
    (5 m) from its path or turned more than ``admissible_yaw_error_rad`` (1.57 rad)
    from its heading. The position limit here scales with the car: ``position_wheelbases``
    wheelbases (default 6: 2.0 m for the 1:10 F1TENTH car, beyond the half-width of
    its tracks, so that the check only fires where the car cannot be on the track;
    Autoware's 5 m is 1.8 wheelbases of its 2.79 m car on a road with a 1.75 m half-width).

    Parameters
    ----------
    position_wheelbases : float
        Largest distance from the reference path, in wheelbases (> 0).
    heading : float
        Largest heading error from the path's heading (rad, > 0).
    """

    position_wheelbases: float = 6.0
    heading: float = 1.57

    def __post_init__(self) -> None:
        for name in ("position_wheelbases", "heading"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ParameterError(f"AdmissibleErrors.{name} must be finite and > 0, got {value!r}")

    def position(self, wheelbase: float) -> float:
        """The largest distance from the path (m) for a car of this wheelbase (m)."""
        return self.position_wheelbases * wheelbase


def stop_command(previous: Command | None) -> Command:
    """Speed 0 (m/s), the wheel held at the previous command's angle (rad; straight when none)."""
    return Command(0.0, 0.0 if previous is None else float(previous.steer))


@dataclass
class StepInfo:
    """Diagnostics of the last :meth:`Controller.step`.

    Parameters
    ----------
    status : str
        One of :data:`STATUSES`: ``"ok"`` on success, else why the command is a fall-back.
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

    Subclasses implement :meth:`_reset` and :meth:`_step`; this class checks every
    observation and command, catches the controller's exceptions, times every step and
    counts the fall-backs by status. A controller that tracks a reference passes it and
    its car's wheelbase here: this class then projects the car once per step (hinted by
    the last admitted projection, :attr:`projection`) and checks the admissible errors.

    Parameters
    ----------
    reference : Reference, optional
        The path the controller tracks; None for a controller that tracks none.
    wheelbase : float
        The car's wheelbase (m), the scale of the admissible position error.
    admissible : AdmissibleErrors, optional
        The limits (:class:`AdmissibleErrors` defaults).

    Attributes
    ----------
    fallback_count : int
        Steps since :meth:`reset` whose status was not ``"ok"``.
    status_counts : collections.Counter
        Steps since :meth:`reset` by status.
    projection : Projection or None
        The car's projection onto the reference at the last admitted step.
    """

    #: Registry name of the controller (``"lmpc"``, ``"pp"``, ...).
    name: str = "controller"
    #: Control period the controller plans with (s); None for one that plans with none.
    dt: float | None = None
    #: Optional observation fields (:data:`OPTIONAL_FIELDS`) this controller needs measured.
    measured_fields: tuple[str, ...] = ()
    #: The field of :class:`~rkmpc.control.settings.ControllerSettings` it is configured by (or None).
    settings_field: str | None = None
    #: Whether it is built from a learned or identified model (:meth:`from_settings` passes it).
    takes_model: bool = False

    @classmethod
    def from_settings(
        cls, reference: Reference, vehicle: VehicleParams, settings: Any, model: object = None
    ) -> Controller:
        """This controller for a car: its field of ``settings`` (:attr:`settings_field`) and, when
        :attr:`takes_model`, its learned or identified ``model`` (subclasses built differently
        override this).

        ``settings`` is the car's :class:`rkmpc.control.settings.ControllerSettings` (a module above
        this one: it holds the settings classes of the controllers built on this base).

        Raises
        ------
        ParameterError
            When a model is given to a controller that takes none, or none to one that needs it.
        """
        build: Any = cls  # every registered controller takes (reference, vehicle[, model][, its settings])
        args: list[object] = [reference, vehicle]
        if cls.takes_model:
            args.append(cls.require_model(model))
        elif model is not None:
            raise ParameterError(f"controller {cls.name!r} takes no model")
        if cls.settings_field is not None:
            args.append(getattr(settings, cls.settings_field))
        made: Controller = build(*args)
        return made

    @classmethod
    def require_model(cls, model: object) -> object:
        """``model``, or ParameterError when it is None (a learned controller needs one)."""
        if model is None:
            raise ParameterError(f"controller {cls.name!r} needs model= (its learned or identified model)")
        return model

    def __init__(
        self,
        reference: Reference | None = None,
        wheelbase: float = 1.0,
        admissible: AdmissibleErrors | None = None,
    ) -> None:
        self.admissible = admissible if admissible is not None else AdmissibleErrors()
        self._tracked = reference
        self._max_position_error = self.admissible.position(wheelbase)
        self.info = StepInfo()
        self.fallback_count = 0
        self.step_count = 0
        self.status_counts: Counter[str] = Counter()
        self.projection: Projection | None = None
        self._last_command: Command | None = None

    def reset(self) -> None:
        """Forget all internal state (warm starts, previous inputs, counters)."""
        self.info = StepInfo()
        self.fallback_count = 0
        self.step_count = 0
        self.status_counts = Counter()
        self.projection = None
        self._last_command = None
        self._reset()

    def step(self, observation: Observation) -> Command:
        """Compute the command for this control period; never raises.

        Parameters
        ----------
        observation : Observation
            The car's current observation.

        Returns
        -------
        Command
            Speed (m/s) and front wheel angle (rad) set-points, always finite; the safe
            :func:`stop_command` when the step was refused or failed (see :attr:`info`).
        """
        t0 = perf_counter()
        command, status, message = self._guarded_step(observation)
        check_interrupted()  # Ctrl-C that a solver swallowed during the step ends the run here
        elapsed = perf_counter() - t0
        self.step_count += 1
        self.status_counts[status] += 1
        if status != "ok":
            self.fallback_count += 1
        self._last_command = command
        self.info = StepInfo(status=status, solve_time_s=elapsed, message=message)
        return command

    def _guarded_step(self, observation: Observation) -> tuple[Command, str, str]:
        """The checks around :meth:`_step`: ``(command, status, message)``."""
        refused = self._refusal(observation)
        if refused is not None:
            return stop_command(self._last_command), refused[0], refused[1]
        try:
            command, status, message = self._step(observation)
        except Exception as exc:  # a run must never crash on a controller's error
            raise_if_interrupted(exc)  # but Ctrl-C inside a solver ends it
            _LOG.debug("%s step %d raised", self.name, self.step_count, exc_info=True)
            return stop_command(self._last_command), "exception", f"{type(exc).__name__}: {exc}"
        if not (math.isfinite(command.speed) and math.isfinite(command.steer)):
            message = f"non-finite command (speed {command.speed}, steer {command.steer})"
            return stop_command(self._last_command), "nonfinite_command", message
        return command, status, message

    def _refusal(self, observation: Observation) -> tuple[str, str] | None:
        """``(status, message)`` when the observation may not be acted on, else None.

        Sets :attr:`projection` (and the next step's projection hint) only when it admits.
        """
        for name in (*REQUIRED_FIELDS, *OPTIONAL_FIELDS):
            value = getattr(observation, name)
            needed = name in REQUIRED_FIELDS or name in self.measured_fields
            if not (math.isfinite(value) or (math.isnan(value) and not needed)):
                return "invalid_input", f"observation {name} is {value!r}"
        if self._tracked is None:
            return None
        hint = None if self.projection is None else self.projection.s
        proj = self._tracked.project(observation.x, observation.y, hint)
        heading_error = wrap_scalar(observation.yaw - proj.heading)
        if not abs(proj.lateral) <= self._max_position_error:
            limit = self._max_position_error
            return "inadmissible", f"{abs(proj.lateral):.3g} m from the path (admissible {limit:.3g} m)"
        if not abs(heading_error) <= self.admissible.heading:
            limit = self.admissible.heading
            return "inadmissible", f"heading error {heading_error:.3g} rad (admissible {limit:.3g} rad)"
        self.projection = proj
        return None

    def _projected(self) -> Projection:
        """The car's projection of this step (:attr:`projection`), for a controller that tracks."""
        if self.projection is None:
            raise RuntimeError(f"{type(self).__name__} tracks no reference: no projection")
        return self.projection

    def diagnostics(self) -> dict[str, float]:
        """Counts and figures of the run so far beyond the fall-backs (none by default)."""
        return {}

    @abstractmethod
    def _reset(self) -> None:
        """Reset subclass state."""

    @abstractmethod
    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        """Return ``(command, status, message)``; status is one of :data:`STATUSES`."""
