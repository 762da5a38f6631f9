"""What ``rkmpc node`` does each control period, without ROS: safety, latency, controller, record.

:class:`CarDriver` holds the controller, the reference and the :class:`SafetyMonitor`. The ROS
node (:mod:`rkmpc.ros.node`) feeds it odometry and measured wheel angles as they arrive and asks
it for a :class:`Decision` once per period (or per odometry message in lock-step); everything it
decides is kept in :attr:`CarDriver.records` and passed to the :attr:`CarDriver.hooks` (a bag
writer, a test), so a run can be recorded and read back.

Two clocks: ``time`` arguments are the clock of the commands (the node's, or in lock-step the
odometry stamps), used for latency compensation; ``wall`` arguments are a monotonic clock
(s), used for the odometry's age, so a simulated clock that stops cannot hide a dead car.
"""

from __future__ import annotations

import math
import traceback
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

from rkmpc.config.ros import RosSettings
from rkmpc.control.base import Controller
from rkmpc.core.angles import wrap_scalar
from rkmpc.core.observation import Command, Observation
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator
from rkmpc.ros.latency import CommandHistory, propagate
from rkmpc.ros.safety import SafetyMonitor, stop_command
from rkmpc.track.reference import Reference
from rkmpc.vehicle.params import VehicleParams

__all__ = ["CarDriver", "Decision"]


@dataclass(frozen=True)
class Decision:
    """One command and why (SI units; NaN where a figure does not apply).

    Parameters
    ----------
    command : Command
        What is sent.
    state : str
        The safety state (:data:`rkmpc.ros.safety.STATES`); every state but ``"running"`` is a stop.
    time : float
        When it was decided, on the commands' clock (s).
    wall : float
        When it was decided, on the monotonic clock (s).
    odometry_age_s : float
        Age of the newest odometry (s).
    lateral_error_m, heading_error_rad : float
        Of the newest odometry against the reference path.
    solve_time_s : float
        The controller's step time (s).
    status : str
        The controller's step status (``"ok"``, ``"fallback"``), empty when it did not run.
    observation : Observation or None
        The odometry the decision was made from, as received (with the measured or estimated
        wheel angle, where there is one).
    fresh : bool
        Whether that odometry arrived after the previous decision (its age is then the
        odometry-to-command latency).
    message : str
        Why a stop was commanded, when there is more to say than the state.
    """

    command: Command
    state: str
    time: float
    wall: float
    odometry_age_s: float = math.nan
    lateral_error_m: float = math.nan
    heading_error_rad: float = math.nan
    solve_time_s: float = math.nan
    status: str = ""
    observation: Observation | None = None
    fresh: bool = False
    message: str = ""

    @property
    def stop(self) -> bool:
        """Whether this is a stop command."""
        return self.state != "running"


class CarDriver:
    """Safety, latency compensation and the controller, period by period.

    Parameters
    ----------
    controller : Controller
        Any controller (reset here).
    reference : Reference
        The path and speed profile the controller tracks (for the errors the safety checks).
    vehicle : VehicleParams
        The controllers' car (wheelbase, ``lr``, servo).
    config : RosSettings
        Safety limits, latency, the odometry's pose reference, the steering source.
    records : int
        How many decisions :attr:`records` keeps.
    """

    def __init__(
        self,
        controller: Controller,
        reference: Reference,
        vehicle: VehicleParams,
        config: RosSettings,
        *,
        records: int = 200_000,
    ) -> None:
        self.controller = controller
        self.reference = reference
        self.vehicle = vehicle
        self.config = config
        self.safety = SafetyMonitor(config.safety)
        latency = config.latency
        self.history = CommandHistory(keep=latency.odometry + latency.actuation + 1.0)
        self.wheel = (
            WheelAnglePropagator(SteeringModel.nominal(vehicle), config.period)
            if config.steering_estimate and config.topics.steering is None
            else None
        )
        #: The decisions so far, oldest first.
        self.records: deque[Decision] = deque(maxlen=records)
        #: Called with every decision, after it is recorded.
        self.hooks: list[Callable[[Decision], None]] = []
        self.controller_errors = 0
        self.nonfinite_commands = 0
        self.last_error = ""
        self._odometry: Observation | None = None
        self._received = math.nan
        self._received_wall = math.nan
        self._pending = False
        self._fresh = False
        self._steer = math.nan
        self._steer_fresh = False
        self._s_hint: float | None = None
        self._errors = (math.nan, math.nan)
        self._last: Command | None = None
        controller.reset()

    @property
    def last_command(self) -> Command | None:
        """The last command sent, None before the first."""
        return self._last

    def on_odometry(self, observation: Observation, time: float, wall: float) -> None:
        """An odometry (converted: centre of gravity, track frame) arrived at ``time`` and ``wall`` (s)."""
        self._odometry = observation
        self._received = float(time)
        self._received_wall = float(wall)
        self._pending = True
        self._fresh = True
        proj = self.reference.path.project(observation.x, observation.y, self._s_hint)
        self._s_hint = float(proj.s)
        self._errors = (float(proj.lateral), wrap_scalar(observation.yaw - float(proj.heading)))

    def on_steering(self, angle: float) -> None:
        """A measured front wheel angle (rad) arrived."""
        self._steer = float(angle)
        self._steer_fresh = True

    def answerable(self) -> bool:
        """In lock-step: an odometry not yet answered, and a wheel angle after it where the car has one."""
        return self._pending and (self.config.topics.steering is None or self._steer_fresh)

    def odometry_age(self, wall: float) -> float | None:
        """Time since the newest odometry arrived (s), None before the first."""
        return None if self._odometry is None else float(wall) - self._received_wall

    def step(self, time: float, wall: float) -> Decision:
        """The command for this period: the controller's, or a stop with the reason."""
        age = self.odometry_age(wall)
        lateral, heading = self._errors
        state = self.safety.check(age, lateral, heading)
        base = Decision(
            stop_command(self._last),
            state,
            float(time),
            float(wall),
            odometry_age_s=math.nan if age is None else age,
            lateral_error_m=lateral,
            heading_error_rad=heading,
            observation=self._odometry,
            fresh=self._fresh,
        )
        # Any answer, a stop included, answers the pending odometry (lock-step).
        self._pending = False
        self._steer_fresh = False
        if state != "running" or self._odometry is None:
            return self._send(base, add_to_history=True)
        measured = self._with_measured_steer(self._odometry)
        base = replace(base, observation=measured)
        seen = self._as_of_step(measured, time)
        try:
            command = self.controller.step(seen)
        except Exception as exc:  # any controller failure stops the car; the node lives on
            self.controller_errors += 1
            self.last_error = "".join(traceback.format_exception_only(exc)).strip()
            return self._send(
                replace(base, state="controller_error", message=self.last_error), add_to_history=True
            )
        info = self.controller.info
        # The controller's base class catches its own failures and answers them with a stop; the
        # node counts them by the status it reports, as it counts the failures it catches itself.
        if info.status == "exception":
            self.controller_errors += 1
            self.last_error = info.message
            return self._send(
                replace(base, state="controller_error", message=info.message), add_to_history=True
            )
        checked, state = self.safety.checked_command(command)
        if state != "running" or info.status == "nonfinite_command":
            self.nonfinite_commands += 1
            checked, state = base.command, "nonfinite_command"
        decision = replace(
            base,
            command=checked,
            state=state,
            solve_time_s=info.solve_time_s,
            status=info.status,
            message=info.message,
        )
        return self._send(decision, add_to_history=True)

    def watchdog(self, time: float, wall: float) -> Decision | None:
        """A stop when the odometry has gone stale (for lock-step, where commands answer odometry)."""
        age = self.odometry_age(wall)
        if age is None or age <= self.config.safety.odometry_timeout:
            return None
        lateral, heading = self._errors
        decision = Decision(
            stop_command(self._last),
            "no_odometry",
            float(time),
            float(wall),
            odometry_age_s=age,
            lateral_error_m=lateral,
            heading_error_rad=heading,
            observation=self._odometry,
        )
        # Not in the latency history: in lock-step it runs on another clock than the answers.
        return self._send(decision, add_to_history=False)

    def shutdown(self, time: float, wall: float) -> Decision:
        """The final stop command."""
        age = self.odometry_age(wall)
        decision = Decision(
            stop_command(self._last),
            "shutdown",
            float(time),
            float(wall),
            odometry_age_s=math.nan if age is None else age,
            observation=self._odometry,
        )
        return self._send(decision, add_to_history=True)

    def _with_measured_steer(self, observation: Observation) -> Observation:
        """The odometry with the wheel angle: measured, or estimated from the commands, where asked."""
        if self.config.topics.steering is not None:
            return replace(observation, steer_angle=self._steer)
        if self.wheel is not None:
            previous = None if self._last is None else self._last.steer
            return replace(observation, steer_angle=self.wheel.step(previous))
        return observation

    def _as_of_step(self, observation: Observation, time: float) -> Observation:
        """What the controller is given: the odometry moved to when the command acts, else dated."""
        latency = self.config.latency
        if not latency.compensate:
            return self._dated(observation, time)
        return propagate(
            observation,
            self.history,
            self._received,
            time,
            odometry=latency.odometry,
            actuation=latency.actuation,
            wheelbase=self.vehicle.wheelbase,
        )

    def _dated(self, observation: Observation, time: float) -> Observation:
        """The odometry dated at this step, its pose at its own time (real time: a timer's step).

        A step later than the odometry's arrival (by ``age``) dates the observation ``age`` after
        its stamp and keeps the pose's time (``pose_time``, else the stamp): a state estimator in
        front of the controller then predicts to the step instead of planning from the odometry's
        instant. Its speed and yaw rate count as current. In lock-step the age is 0.
        """
        age = float(time) - self._received
        if not age > 0.0:
            return observation
        pose_time = observation.pose_time if math.isfinite(observation.pose_time) else observation.time
        return replace(observation, time=observation.time + age, pose_time=pose_time)

    def _send(self, decision: Decision, *, add_to_history: bool) -> Decision:
        self._last = decision.command
        self._fresh = False
        if add_to_history:
            self.history.add(decision.time, decision.command)
        self.safety.record(decision.state)
        self.records.append(decision)
        for hook in self.hooks:
            hook(decision)
        return decision
