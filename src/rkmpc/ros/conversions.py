"""ROS messages to the project's records and back: odometry, drive commands, stamps.

The functions fill or read messages by their fields (``nav_msgs/msg/Odometry``,
``ackermann_msgs/msg/AckermannDriveStamped``, ``builtin_interfaces/msg/Time``) and import no
ROS package themselves, so they run on any object with those fields.

Odometry follows ROS' convention (REP 103/105): the pose in the ``header.frame_id`` frame
(``map``), the twist in the body frame ``child_frame_id``: ``linear.x`` forward, ``linear.y``
to the left (m/s), ``angular.z`` the yaw rate (rad/s).
"""

from __future__ import annotations

import math
from typing import Any

from rkmpc.core.observation import Command, Observation

__all__ = [
    "command_from_drive",
    "fill_drive",
    "fill_odometry",
    "observation_from_odometry",
    "quaternion_from_yaw",
    "seconds_of",
    "set_stamp",
    "yaw_from_quaternion",
]


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Heading (rad, in ``(-pi, pi]``) of a rotation given as a quaternion (any norm)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)) if (x or y or z or w) else 0.0


def quaternion_from_yaw(yaw: float) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of a rotation by ``yaw`` (rad) about the vertical."""
    return 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)


def seconds_of(stamp: Any) -> float:
    """A ``builtin_interfaces/msg/Time`` as seconds."""
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def set_stamp(stamp: Any, seconds: float) -> None:
    """Write ``seconds`` (>= 0) into a ``builtin_interfaces/msg/Time``, to the nanosecond."""
    total = round(seconds * 1e9)
    stamp.sec, stamp.nanosec = divmod(int(total), 1_000_000_000)


def observation_from_odometry(
    msg: Any,
    *,
    rear_axle_to_cog: float = 0.0,
    steer: float = math.nan,
    lateral_velocity: bool = True,
    yaw_rate: bool = True,
    pose_latency: float = 0.0,
) -> Observation:
    """The observation an odometry message reports.

    Parameters
    ----------
    msg : nav_msgs/msg/Odometry
        Pose in the map frame, twist in the body frame.
    rear_axle_to_cog : float
        When the pose is the rear axle's, the distance to the centre of gravity (m, the car's
        ``lr``); 0 when the pose is the centre of gravity's.
    steer : float
        Measured front wheel angle (rad), NaN when not measured.
    lateral_velocity, yaw_rate : bool
        Whether ``twist.linear.y`` and ``twist.angular.z`` are measured; when not, the slip angle
        and the yaw rate are NaN (unmeasured), never 0.
    pose_latency : float
        How much older than the stamp the pose is (s, >= 0): a localiser's processing delay, when
        its pose travels in an odometry stamped as the twist is. 0: as current as the stamp.

    Returns
    -------
    Observation
        Position of the centre of gravity, heading, ``speed`` = ``twist.linear.x`` (along the
        heading), yaw rate = ``twist.angular.z``, slip angle = ``atan2(vy, vx)`` (0 at standstill),
        ``time`` = the header stamp (s); ``pose_time`` = the stamp less ``pose_latency``, NaN
        where that is 0 (the pose is as current as its stamp). A message that repeats the last
        pose is no new pose for the state estimator.
    """
    pose = msg.pose.pose
    q = pose.orientation
    yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
    twist = msg.twist.twist
    vx, vy = float(twist.linear.x), float(twist.linear.y)
    stamp = seconds_of(msg.header.stamp)
    return Observation(
        x=float(pose.position.x) + rear_axle_to_cog * math.cos(yaw),
        y=float(pose.position.y) + rear_axle_to_cog * math.sin(yaw),
        yaw=yaw,
        speed=vx,
        yaw_rate=float(twist.angular.z) if yaw_rate else math.nan,
        slip_angle=(math.atan2(vy, vx) if (vx or vy) else 0.0) if lateral_velocity else math.nan,
        steer_angle=float(steer),
        time=stamp,
        pose_time=stamp - pose_latency if pose_latency > 0.0 else math.nan,
    )


def fill_odometry(msg: Any, observation: Observation, *, frame: str, child_frame: str) -> None:
    """Write an observation into an odometry message (the stamp is left to the caller).

    The twist is the body-frame velocity ``(speed, speed tan(slip))`` and the yaw rate; NaN
    yaw rate or slip (an observation that does not measure them) are written as 0.
    """
    msg.header.frame_id = frame
    msg.child_frame_id = child_frame
    pose = msg.pose.pose
    pose.position.x, pose.position.y, pose.position.z = float(observation.x), float(observation.y), 0.0
    qx, qy, qz, qw = quaternion_from_yaw(observation.yaw)
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = qx, qy, qz, qw
    slip = observation.slip_angle if math.isfinite(observation.slip_angle) else 0.0
    yaw_rate = observation.yaw_rate if math.isfinite(observation.yaw_rate) else 0.0
    twist = msg.twist.twist
    twist.linear.x = float(observation.speed)
    twist.linear.y = float(observation.speed) * math.tan(slip)
    twist.angular.z = float(yaw_rate)


def fill_drive(msg: Any, command: Command, *, frame: str) -> None:
    """Write a command into an ``AckermannDriveStamped`` (speed m/s, steering angle rad; stamp left)."""
    msg.header.frame_id = frame
    msg.drive.speed = float(command.speed)
    msg.drive.steering_angle = float(command.steer)


def command_from_drive(msg: Any) -> Command:
    """The command of an ``AckermannDriveStamped``: ``drive.speed`` and ``drive.steering_angle``."""
    return Command(float(msg.drive.speed), float(msg.drive.steering_angle))
