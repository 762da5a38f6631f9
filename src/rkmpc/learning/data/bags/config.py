"""What a bag import and a bag writer are told: topics, frames, time base, resampling (no ROS needed)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_finite_real, is_integer, is_positive_number, require_choice
from rkmpc.learning.data.resampling import GapAndTolerance
from rkmpc.learning.data.window import TimeWindow

__all__ = [
    "DEFAULT_CHILD_FRAME",
    "DEFAULT_DRIVE_TOPIC",
    "DEFAULT_MAP_FRAME",
    "DEFAULT_ODOM_TOPIC",
    "ODOM_FRAMES",
    "STAMP_SOURCES",
    "STORAGES",
    "BagImportConfig",
    "BagWriteConfig",
]

#: Odometry topic of the F1TENTH simulator's ROS bridge (ForzaETH's race_stack uses ``/car_state/odom``).
DEFAULT_ODOM_TOPIC = "/ego_racecar/odom"
#: Command topic of the F1TENTH stack (ForzaETH: ``/vesc/high_level/ackermann_cmd_mux/input/nav_1``).
DEFAULT_DRIVE_TOPIC = "/drive"
#: Frames of the F1TENTH simulator's odometry: the pose of ``ego_racecar/base_link`` in ``map``.
DEFAULT_MAP_FRAME = "map"
DEFAULT_CHILD_FRAME = "ego_racecar/base_link"
#: Where the odometry's child frame sits on the car: the centre of gravity or the rear axle's centre.
ODOM_FRAMES = ("cog", "rear-axle")
#: Time base of odometry and commands: the message header's stamp or the bag's receive time.
STAMP_SOURCES = ("header", "receive")
#: Bag formats the writer makes: ROS 2 MCAP (the ROS 2 default), ROS 2 sqlite3, ROS 1 ``.bag``.
STORAGES = ("mcap", "sqlite3", "ros1")


def _topic(obj: object, name: str, optional: bool = False) -> None:
    value = getattr(obj, name)
    if optional and value is None:
        return
    if not (isinstance(value, str) and value.strip() and value == value.strip()):
        raise ParameterError(f"{type(obj).__name__}.{name} must be a topic name, got {value!r}")


@dataclass(frozen=True)
class BagImportConfig(GapAndTolerance):
    """How :func:`rkmpc.learning.data.bags.import_bag` turns a bag into transitions.

    Parameters
    ----------
    dt : float
        Control period (s) the odometry is resampled onto, > 0.
    odom_topic : str
        ``nav_msgs/msg/Odometry`` topic: pose in the map frame, twist in the car's (child) frame.
    drive_topic : str
        ``ackermann_msgs/msg/AckermannDriveStamped`` topic (``drive.speed`` m/s,
        ``drive.steering_angle`` rad).
    steer_topic : str or None
        Optional ``std_msgs/msg/Float64`` (or ``Float32``) topic of the front wheel angle, stamped
        by the bag's receive time (the message has no header); None: ``steer_angle`` is NaN.
    steer_gain, steer_offset : float
        The steer topic carries ``gain * angle + offset``; the angle (rad) is
        ``(value - offset) / gain``. 1 and 0 for a wheel angle in rad; the VESC driver's
        ``steering_angle_to_servo_gain`` and ``..._offset`` for its ``servo_position_command``.
    odom_frame : str
        ``"cog"``: the odometry's child frame is the centre of gravity (the F1TENTH simulator);
        ``"rear-axle"``: it is the centre of the rear axle (moved forward by ``lr`` of the car).
    stamps : str
        ``"header"``: odometry and commands are timed by their header stamps (default);
        ``"receive"``: by the time the bag recorded them (for stacks that leave stamps empty).
    max_gap : float or None
        An odometry gap (s) longer than this starts a new episode; a command older than this is
        no longer held. None: three control periods.
    command_tolerance : float or None
        A command stamped up to this long (s) after a sample counts as that sample's command (the
        controller's timer jitter); in ``[0, dt)``. None: a quarter period. 0 is the strict rule,
        the last command at or before each sample.
    min_slip_speed : float
        Below this speed (m/s) the side-slip angle is not defined and is NaN.
    lateral_velocity : bool
        The odometry's ``twist.linear.y`` is a measured lateral velocity (a simulator's, a state
        estimator's). False: it is not (a particle filter's odometry reports 0) and the side-slip
        angle is NaN, left to the state estimator.
    yaw_rate : bool
        The odometry's ``twist.angular.z`` is a measured yaw rate. False: the yaw rate is NaN.
    min_samples : int
        Fewer transitions than this after resampling are an error ("too little data").
    window : TimeWindow or None
        Keep only this stretch of the bag (seconds from the first message of the topics read, or
        absolute stamps); None: all of it.
    pose_latency : float
        How much older (s) than its stamp the odometry's pose is: a localiser 30 ms late whose
        odometry is stamped when it is sent, as the rkmpc node's simulated car sends it. Recorded as
        the data's ``pose_latency``, by which the labels' smoother dates each pose back
        (:func:`rkmpc.experiments.training.estimated_for`). 0: the stamp is the pose's own time.
    """

    dt: float = 0.05
    odom_topic: str = DEFAULT_ODOM_TOPIC
    drive_topic: str = DEFAULT_DRIVE_TOPIC
    steer_topic: str | None = None
    steer_gain: float = 1.0
    steer_offset: float = 0.0
    odom_frame: str = "cog"
    stamps: str = "header"
    max_gap: float | None = None
    command_tolerance: float | None = None
    min_slip_speed: float = 0.5
    lateral_velocity: bool = True
    yaw_rate: bool = True
    min_samples: int = 20
    window: TimeWindow | None = None
    pose_latency: float = 0.0

    def __post_init__(self) -> None:
        name = type(self).__name__
        if self.window is not None and not isinstance(self.window, TimeWindow):
            raise ParameterError(f"{name}.window must be None or a TimeWindow, got {self.window!r}")
        if not is_positive_number(self.dt):
            raise ParameterError(f"{name}.dt must be finite and > 0, got {self.dt!r}")
        for topic in ("odom_topic", "drive_topic"):
            _topic(self, topic)
        _topic(self, "steer_topic", optional=True)
        topics = [t for t in (self.odom_topic, self.drive_topic, self.steer_topic) if t is not None]
        if len(set(topics)) != len(topics):
            raise ParameterError(f"{name}: the odometry, drive and steer topics must differ, got {topics}")
        if not (is_finite_real(self.steer_gain) and self.steer_gain != 0):
            raise ParameterError(f"{name}.steer_gain must be finite and not 0, got {self.steer_gain!r}")
        if not is_finite_real(self.steer_offset):
            raise ParameterError(f"{name}.steer_offset must be finite, got {self.steer_offset!r}")
        require_choice(self, "odom_frame", ODOM_FRAMES)
        require_choice(self, "stamps", STAMP_SOURCES)
        if self.max_gap is not None and not is_positive_number(self.max_gap):
            raise ParameterError(f"{name}.max_gap must be None or finite and > 0, got {self.max_gap!r}")
        tolerance = self.command_tolerance
        if tolerance is not None and not (is_finite_real(tolerance) and 0 <= tolerance < self.dt):
            raise ParameterError(f"{name}.command_tolerance must be None or in [0, dt), got {tolerance!r}")
        if not (is_finite_real(self.min_slip_speed) and self.min_slip_speed >= 0):
            raise ParameterError(
                f"{name}.min_slip_speed must be finite and >= 0, got {self.min_slip_speed!r}"
            )
        if not is_integer(self.min_samples, 1):
            raise ParameterError(f"{name}.min_samples must be an integer >= 1, got {self.min_samples!r}")
        if not (is_finite_real(self.pose_latency) and self.pose_latency >= 0):
            raise ParameterError(f"{name}.pose_latency must be finite and >= 0, got {self.pose_latency!r}")
        for flag in ("lateral_velocity", "yaw_rate"):
            if not isinstance(getattr(self, flag), bool):
                raise ParameterError(f"{name}.{flag} must be true or false, got {getattr(self, flag)!r}")

    def describe(self) -> dict[str, Any]:
        """JSON-able record of the import (for the data set's metadata)."""
        return {
            "dt": self.dt,
            "topics": {"odom": self.odom_topic, "drive": self.drive_topic, "steer": self.steer_topic},
            "steer_gain": self.steer_gain,
            "steer_offset": self.steer_offset,
            "odom_frame": self.odom_frame,
            "stamps": self.stamps,
            "max_gap": self.gap,
            "command_tolerance": self.tolerance,
            "min_slip_speed": self.min_slip_speed,
            "measured": {"lateral_velocity": self.lateral_velocity, "yaw_rate": self.yaw_rate},
            "window": None if self.window is None else self.window.describe(),
            "pose_latency": self.pose_latency,
        }


@dataclass(frozen=True)
class BagWriteConfig:
    """How :func:`rkmpc.learning.data.bags.write_bag` records a run as a bag.

    Parameters
    ----------
    storage : str
        ``"mcap"`` (ROS 2, the default), ``"sqlite3"`` (ROS 2) or ``"ros1"`` (a ``.bag`` file).
    odom_topic, drive_topic : str
        Topics of the odometry and the commands (defaults: the F1TENTH simulator's).
    steer_topic : str or None
        Also record the measured wheel angle (rad) as ``std_msgs/msg/Float64`` on this topic.
    frame_id, child_frame_id : str
        Frames of the odometry: the map and the car.
    odom_frame : str
        Where the child frame sits: ``"cog"`` or ``"rear-axle"`` (``lr`` behind the centre of gravity).
    lr : float or None
        Centre of gravity to rear axle (m), > 0; needed for ``"rear-axle"``.
    start_time : float
        Stamp (s since the epoch of the bag's clock) of the run's time 0, >= 0.
    command_delay : float
        Commands are stamped this long (s) after the odometry they answer (a controller's
        computation time), >= 0.
    """

    storage: str = "mcap"
    odom_topic: str = DEFAULT_ODOM_TOPIC
    drive_topic: str = DEFAULT_DRIVE_TOPIC
    steer_topic: str | None = None
    frame_id: str = DEFAULT_MAP_FRAME
    child_frame_id: str = DEFAULT_CHILD_FRAME
    odom_frame: str = "cog"
    lr: float | None = None
    start_time: float = 0.0
    command_delay: float = 0.0

    def __post_init__(self) -> None:
        name = type(self).__name__
        require_choice(self, "storage", STORAGES)
        for topic in ("odom_topic", "drive_topic", "frame_id", "child_frame_id"):
            _topic(self, topic)
        _topic(self, "steer_topic", optional=True)
        topics = [t for t in (self.odom_topic, self.drive_topic, self.steer_topic) if t is not None]
        if len(set(topics)) != len(topics):
            raise ParameterError(f"{name}: the odometry, drive and steer topics must differ, got {topics}")
        require_choice(self, "odom_frame", ODOM_FRAMES)
        if self.lr is not None and not is_positive_number(self.lr):
            raise ParameterError(f"{name}.lr must be None or finite and > 0, got {self.lr!r}")
        if self.odom_frame == "rear-axle" and self.lr is None:
            raise ParameterError(f"{name}: odom_frame 'rear-axle' needs lr, the rear axle's distance (m)")
        for field in ("start_time", "command_delay"):
            value = getattr(self, field)
            if not (is_finite_real(value) and value >= 0):
                raise ParameterError(f"{name}.{field} must be finite and >= 0, got {value!r}")
