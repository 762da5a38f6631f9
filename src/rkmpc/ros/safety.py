"""When the node stops the car: stale odometry, too large an error, a failing controller.

:class:`SafetyMonitor` decides, before each command, whether the controller may drive
(``"running"``) or the car must stop (every other state). A stop is speed 0 with the wheel
held where the last command put it (:func:`stop_command`). It counts every stop by cause, so
the diagnostics can say how often each happened.

States
------
``"waiting"``
    No odometry yet.
``"running"``
    The controller drives.
``"no_odometry"``
    The last odometry is older than the timeout; lifts when odometry returns.
``"tracking_error"``
    The car is farther from the reference path, or turned farther from its heading, than the
    admissible limits (as Autoware's MPC does); latched until restart unless ``latch`` is off.
``"controller_error"``
    The controller raised; the next period tries again.
``"nonfinite_command"``
    The controller answered NaN or infinity; the next period tries again.
``"shutdown"``
    The node is stopping (Ctrl-C): the final command.
"""

from __future__ import annotations

import math
from collections import Counter

from rkmpc.config.ros import SafetySettings
from rkmpc.control.base import stop_command
from rkmpc.core.observation import Command

__all__ = ["STATES", "SafetyMonitor", "stop_command"]

#: Every state the node can be in; all but ``"running"`` command a stop.
STATES = (
    "waiting",
    "running",
    "no_odometry",
    "tracking_error",
    "controller_error",
    "nonfinite_command",
    "shutdown",
)


class SafetyMonitor:
    """The checks before each command, and the count of stops by state.

    Parameters
    ----------
    settings : SafetySettings
        Timeout (s) and admissible lateral (m) and heading (rad) errors.
    """

    def __init__(self, settings: SafetySettings) -> None:
        self.settings = settings
        self.latched = False
        #: Commands decided in each state (``"running"`` included).
        self.counts: Counter[str] = Counter()

    def check(self, odometry_age: float | None, lateral_error: float, heading_error: float) -> str:
        """The state before the controller runs: ``"running"`` or why the car must stop.

        Parameters
        ----------
        odometry_age : float or None
            Time since the last odometry arrived (s); None before the first.
        lateral_error, heading_error : float
            Of the last odometry against the reference path (m, rad).
        """
        s = self.settings
        if odometry_age is None:
            return "waiting"
        if not odometry_age <= s.odometry_timeout:
            return "no_odometry"
        beyond = not (abs(lateral_error) <= s.max_lateral_error and abs(heading_error) <= s.max_heading_error)
        if beyond and s.latch:
            self.latched = True
        if beyond or self.latched:
            return "tracking_error"
        return "running"

    def checked_command(self, command: Command) -> tuple[Command, str]:
        """The command, speed clipped, and ``"running"``; or ``"nonfinite_command"`` for NaN or inf."""
        if not (math.isfinite(command.speed) and math.isfinite(command.steer)):
            return command, "nonfinite_command"
        limit = self.settings.max_speed
        if limit is not None and command.speed > limit:
            return Command(limit, command.steer), "running"
        return command, "running"

    def record(self, state: str) -> None:
        """Count one command decided in ``state``."""
        self.counts[state] += 1
