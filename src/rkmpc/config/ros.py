"""How ``rkmpc node`` talks to a car over ROS 2: the ``[ros]`` section of a car file.

Topics, frames, how the odometry is read, latency compensation, the safety stops, recording, the
control rate and its trigger: :class:`RosSettings` and its sections. Every key is optional (the
defaults are the F1TENTH simulator's conventions and the paper's 20 Hz) and unknown keys are
refused; a ROS parameter overrides a key by its dotted name within the section
(``--ros-args -p safety.odometry_timeout:=1.0``). This module needs neither ROS nor YAML.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rkmpc.core.validation import (
    require_bool,
    require_choice,
    require_nonnegative,
    require_positive,
    require_positive_or_none,
)
from rkmpc.learning.data.bags.stream import RECORD_STORAGES

__all__ = [
    "Frames",
    "LatencySettings",
    "OdometrySettings",
    "RecordSettings",
    "RosSettings",
    "SafetySettings",
    "Topics",
]

TRIGGERS = ("timer", "odometry")
POSE_REFERENCES = ("cog", "rear_axle")
RELIABILITIES = ("reliable", "best_effort")


@dataclass(frozen=True)
class Topics:
    """Topic names (the F1TENTH simulator bridge's by default).

    Parameters
    ----------
    odometry : str
        ``nav_msgs/msg/Odometry`` in.
    drive : str
        ``ackermann_msgs/msg/AckermannDriveStamped`` out.
    steering : str or None
        ``std_msgs/msg/Float64``, the measured front wheel angle (rad), where the car has it.
    diagnostics : str
        ``diagnostic_msgs/msg/DiagnosticArray`` out.
    """

    odometry: str = "/ego_racecar/odom"
    drive: str = "/drive"
    steering: str | None = None
    diagnostics: str = "/diagnostics"


@dataclass(frozen=True)
class Frames:
    """Frame ids.

    Parameters
    ----------
    map : str or None
        The frame the odometry's pose must be in (a message in another is ignored, with a
        warning); None accepts any.
    drive : str
        ``header.frame_id`` of the commands.
    """

    map: str | None = "map"
    drive: str = "base_link"


@dataclass(frozen=True)
class OdometrySettings:
    """How the odometry is read.

    Parameters
    ----------
    pose : str
        ``"cog"``: the pose is the centre of gravity's (the F1TENTH simulator's); ``"rear_axle"``:
        the rear axle's, moved forward by the car's ``lr`` (m) to the centre of gravity.
    reliability : str
        QoS of the subscription: ``"reliable"`` or ``"best_effort"`` (which also hears reliable
        publishers; use it for a localisation that publishes best effort).
    lateral_velocity : bool
        Whether ``twist.linear.y`` is measured (a simulator's, a motion-capture system's). A real
        car's VESC odometry publishes 0 there: with ``false`` the slip angle is NaN (unmeasured,
        for the state estimator to estimate), never a slip angle of 0. A car whose ``[sensors]``
        measure no side slip (``measures_slip_angle = false``) is read as ``false`` whatever this says.
    yaw_rate : bool
        Whether ``twist.angular.z`` is measured; ``false`` makes the yaw rate NaN.
    """

    pose: str = "cog"
    reliability: str = "reliable"
    lateral_velocity: bool = True
    yaw_rate: bool = True

    def __post_init__(self) -> None:
        require_choice(self, "pose", POSE_REFERENCES)
        require_choice(self, "reliability", RELIABILITIES)
        require_bool(self, "lateral_velocity", "yaw_rate")


@dataclass(frozen=True)
class LatencySettings:
    """Latency compensation (:mod:`rkmpc.ros.latency`).

    Parameters
    ----------
    compensate : bool
        Move each observation over the loop's latency with the kinematic model and the commands
        sent in that window before the controller sees it.
    odometry : float
        Age of the odometry when it arrives (s), >= 0 (a localisation filter's delay).
    actuation : float
        Delay from sending a command to the car acting on it (s), >= 0.
    """

    compensate: bool = False
    odometry: float = 0.0
    actuation: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative(self, "odometry", "actuation")


@dataclass(frozen=True)
class SafetySettings:
    """When the node commands a stop (speed 0, the wheel held where it was).

    Parameters
    ----------
    odometry_timeout : float
        No odometry for longer than this (s) stops the car until odometry returns.
    max_lateral_error : float
        Distance from the reference path (m) beyond which the car is stopped.
    max_heading_error : float
        Heading error (rad) beyond which the car is stopped.
    latch : bool
        A stop for a too large error holds until the node is restarted (True), or lifts when the
        error is back within its limit (False).
    max_speed : float or None
        Commanded speeds are clipped to this (m/s); None for no clip beyond the controller's own.
    """

    odometry_timeout: float = 0.5
    max_lateral_error: float = 1.0
    max_heading_error: float = 1.0
    latch: bool = True
    max_speed: float | None = None

    def __post_init__(self) -> None:
        require_positive(self, "odometry_timeout", "max_lateral_error", "max_heading_error")
        require_positive_or_none(self, "max_speed")


@dataclass(frozen=True)
class RecordSettings:
    """Recording what the node saw and sent to a bag (``rkmpc node --record``).

    Parameters
    ----------
    bag : str or None
        The ROS 2 bag folder to write; it must not exist. ``{time}`` in it becomes the node's
        start time (``20250131-142501``). None records nothing.
    storage : str
        ``"mcap"`` (the ROS 2 default) or ``"sqlite3"``.
    """

    bag: str | None = None
    storage: str = "mcap"

    def __post_init__(self) -> None:
        require_choice(self, "storage", RECORD_STORAGES)


@dataclass(frozen=True, kw_only=True)
class RosSettings:
    """Everything ``rkmpc node`` needs to talk to one car (SI units), the ``[ros]`` section.

    Parameters
    ----------
    rate_hz : float
        Control rate (Hz); the controllers plan with its inverse as their period (the paper's
        20 Hz: 0.05 s).
    trigger : str
        ``"timer"``: one command per period of a wall-clock timer, from the latest odometry (a
        car). ``"odometry"``: one command per odometry message, stamped with its stamp (the
        simulated car's lock-step mode); a wall-clock watchdog still stops the car.
    steering_estimate : bool
        Without a steering topic, estimate the wheel angle from the commands sent (the vehicle's
        nominal servo, lag and rate limit: :class:`rkmpc.estimation.steering.SteeringModel`), for
        controllers that use it; NaN otherwise.
    topics, frames, odometry, latency, safety, record
        The sections below.
    """

    rate_hz: float = 20.0
    trigger: str = "timer"
    steering_estimate: bool = False
    topics: Topics = field(default_factory=Topics)
    frames: Frames = field(default_factory=Frames)
    odometry: OdometrySettings = field(default_factory=OdometrySettings)
    latency: LatencySettings = field(default_factory=LatencySettings)
    safety: SafetySettings = field(default_factory=SafetySettings)
    record: RecordSettings = field(default_factory=RecordSettings)

    def __post_init__(self) -> None:
        require_positive(self, "rate_hz")
        require_choice(self, "trigger", TRIGGERS)

    @property
    def period(self) -> float:
        """The control period (s)."""
        return 1.0 / self.rate_hz
