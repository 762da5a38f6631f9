"""Bags: what a car (or the ROS nodes) recorded, read as a transition data set, and runs written as bags.

:func:`import_bag` reads ROS 1 ``.bag`` files and ROS 2 bags (sqlite3 and MCAP) through the
``rosbags`` package (``pip install 'rkmpc[bags]'``; no ROS installation needed): odometry
(``nav_msgs/msg/Odometry``), commands (``ackermann_msgs/msg/AckermannDriveStamped``) and an
optional wheel-angle topic, resampled onto the control period
(:mod:`~rkmpc.learning.data.bags.resample`). :func:`write_bag` and :func:`write_log_bag` record a
run the same way a car's stack would; :class:`BagStreamWriter` writes messages as they come (the
recorder of ``rkmpc node --record``). Importing this package does not import ``rosbags``; reading
or writing a bag does.
"""

from __future__ import annotations

from rkmpc.learning.data.bags.config import (
    DEFAULT_DRIVE_TOPIC,
    DEFAULT_ODOM_TOPIC,
    ODOM_FRAMES,
    STORAGES,
    BagImportConfig,
    BagWriteConfig,
)
from rkmpc.learning.data.bags.importer import import_bag
from rkmpc.learning.data.bags.stream import RECORD_STORAGES, BagStreamWriter
from rkmpc.learning.data.bags.write import write_bag, write_log_bag

__all__ = [
    "DEFAULT_DRIVE_TOPIC",
    "DEFAULT_ODOM_TOPIC",
    "ODOM_FRAMES",
    "RECORD_STORAGES",
    "STORAGES",
    "BagImportConfig",
    "BagStreamWriter",
    "BagWriteConfig",
    "import_bag",
    "write_bag",
    "write_log_bag",
]
