"""The message types of a car's bag and the ``rosbags`` type store that knows them.

``rosbags`` ships the ROS 1 and ROS 2 standard messages (``nav_msgs``, ``std_msgs``) but not
``ackermann_msgs``; its two definitions are registered here from their ``.msg`` text, so the type
names, the ROS 1 MD5 sums and the ROS 2 type hashes are those of the upstream package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "ACKERMANN_DRIVE",
    "ACKERMANN_DRIVE_MSG",
    "ACKERMANN_DRIVE_STAMPED",
    "ACKERMANN_DRIVE_STAMPED_MSG",
    "INSTALL_HINT",
    "ODOMETRY",
    "STEER_TYPES",
    "typestore",
]

ODOMETRY = "nav_msgs/msg/Odometry"
ACKERMANN_DRIVE = "ackermann_msgs/msg/AckermannDrive"
ACKERMANN_DRIVE_STAMPED = "ackermann_msgs/msg/AckermannDriveStamped"
#: Types a steer topic may carry: one number, the wheel angle (or a servo position).
STEER_TYPES = ("std_msgs/msg/Float64", "std_msgs/msg/Float32")
FLOAT64 = "std_msgs/msg/Float64"

#: ``ackermann_msgs/msg/AckermannDrive`` (ROS 1 and ROS 2 alike; comments left out).
ACKERMANN_DRIVE_MSG = """\
float32 steering_angle
float32 steering_angle_velocity
float32 speed
float32 acceleration
float32 jerk
"""
#: ``ackermann_msgs/msg/AckermannDriveStamped``.
ACKERMANN_DRIVE_STAMPED_MSG = """\
std_msgs/Header header
AckermannDrive drive
"""

INSTALL_HINT = "reading and writing bags needs the rosbags package: pip install 'rkmpc[bags]'"


def typestore(ros1: bool) -> Typestore:
    """A type store of ROS 1 Noetic (``ros1``) or ROS 2 Humble with ``ackermann_msgs`` registered.

    Raises
    ------
    ImportError
        When ``rosbags`` is not installed (with the command that installs it).
    """
    try:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(INSTALL_HINT) from exc
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    store.register(
        {
            **get_types_from_msg(ACKERMANN_DRIVE_MSG, ACKERMANN_DRIVE),
            **get_types_from_msg(ACKERMANN_DRIVE_STAMPED_MSG, ACKERMANN_DRIVE_STAMPED),
        }
    )
    return store
