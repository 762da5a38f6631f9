"""Built-in CSV log layouts: :data:`PRESETS`, by name.

``friction-maps``: the ``stateLogger.py`` of the FrictionMaps project (an F1TENTH car driven by
remote control; particle-filter localisation on a lidar map, VESC motor controller and IMU). Every
file is stamped with a ROS stamp in two columns, ``s`` and ``ns``; the first, unnamed column is a
pandas index. Checked against the other sensors on two runs (``../shared/real/f1tenth-car``):

* pose from ``pfPoseData.csv`` (``x, y`` in m, the orientation quaternion ``q.x .. q.w``);
* speed from ``odomData.csv``'s ``vx``: the VESC's speed, under its own stamps.
  ``pfOdomData.csv``'s ``vx`` holds the same values re-stamped at the particle filter's updates
  (the same number appears there a median 25 ms later), so it is the same sensor, only late.
  (Both files' ``wx`` repeat ``vx`` and their ``wz`` is 0 in every row: no yaw rate there.)
* yaw rate from ``imuData.csv``'s ``wz`` in **deg/s**: the logger's notes say rad/s, but the
  column matches the yaw rate of the pose only after a factor of about 57 (180/pi);
* commands from ``commandData.csv``: ``V`` (m/s) and ``delta`` (rad).

The notes do not say which point of the car the pose is of; it is taken as the centre of gravity.
A joystick's commands come irregularly (one run has 79 intervals over 0.15 s, the longest 0.32 s),
so a command holds 0.5 s.
"""

from __future__ import annotations

from rkmpc.learning.data.logs.spec import CommandSource, CsvLogSpec, PoseSource, TimeColumns, ValueSource

__all__ = ["FRICTION_MAPS", "PRESETS"]

_ROS_STAMP = TimeColumns(seconds="s", nanoseconds="ns")

#: The FrictionMaps logger's layout (module docstring).
FRICTION_MAPS = CsvLogSpec(
    name="friction-maps",
    description=(
        "FrictionMaps stateLogger.py (F1TENTH car): pose from pfPoseData, speed from odomData.vx "
        "(the VESC's, on its own stamps; pfOdomData repeats it later), yaw rate from imuData.wz "
        "in deg/s (documented as rad/s), commands from commandData"
    ),
    pose=PoseSource(
        file="pfPoseData.csv",
        time=_ROS_STAMP,
        x="x",
        y="y",
        quaternion=("q.x", "q.y", "q.z", "q.w"),
    ),
    speed=ValueSource(file="odomData.csv", time=_ROS_STAMP, column="vx", unit="m/s"),
    yaw_rate=ValueSource(file="imuData.csv", time=_ROS_STAMP, column="wz", unit="deg/s"),
    command=CommandSource(file="commandData.csv", time=_ROS_STAMP, speed="V", steer="delta"),
    command_hold=0.5,
)

#: Presets by name.
PRESETS: dict[str, CsvLogSpec] = {FRICTION_MAPS.name: FRICTION_MAPS}
