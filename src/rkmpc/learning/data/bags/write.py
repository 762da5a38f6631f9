"""Record a run as a bag: odometry and Ackermann commands, as a car's stack would have recorded them.

The odometry (``nav_msgs/msg/Odometry``) gives the pose of the child frame in the map frame and
its twist in the child frame: ``linear.x`` the speed along the heading, ``linear.y = speed *
tan(slip_angle)`` the lateral velocity, ``angular.z`` the yaw rate; covariances are zero. The
commands are ``ackermann_msgs/msg/AckermannDriveStamped`` (``drive.speed``, ``drive.steering_angle``,
float32 on the wire). Header stamps and the bag's receive times agree.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.data.bags.config import BagWriteConfig
from rkmpc.learning.data.bags.resample import odometry_at_cog
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, FLOAT64, ODOMETRY, typestore
from rkmpc.learning.data.dataset import StepTable

__all__ = ["write_bag", "write_log_bag"]

_NS = 1_000_000_000
_REQUIRED = ("x", "y", "yaw", "speed", "yaw_rate", "slip_angle")


def write_log_bag(path: str | Path, log: StepTable, config: BagWriteConfig | None = None) -> Path:
    """Record a closed-loop step log (:class:`rkmpc.sim.log.StepLog`) as a bag.

    Uses the columns ``t`` (s), :data:`~rkmpc.core.observation.OBSERVATION_FIELDS` and
    ``cmd_speed``, ``cmd_steer``; see :func:`write_bag`.
    """
    missing = [c for c in ("t", *OBSERVATION_FIELDS, "cmd_speed", "cmd_steer") if c not in log.columns]
    if missing:
        raise ParameterError(f"write_log_bag: the log lacks the columns {missing}")
    obs = np.stack([np.asarray(log[c], dtype=float) for c in OBSERVATION_FIELDS], axis=1)
    command = np.stack(
        [np.asarray(log["cmd_speed"], dtype=float), np.asarray(log["cmd_steer"], dtype=float)], 1
    )
    return write_bag(path, np.asarray(log["t"], dtype=float), obs, command, config)


def write_bag(
    path: str | Path,
    times: np.ndarray,
    obs: np.ndarray,
    command: np.ndarray,
    config: BagWriteConfig | None = None,
) -> Path:
    """Write observations and the commands sent at them as a ROS 1, ROS 2 sqlite3 or MCAP bag.

    Parameters
    ----------
    path : str or Path
        The bag: a file ending in ``.bag`` for ROS 1, a folder for ROS 2 (``ros2 bag``'s layout).
        It must not exist; it is written in a temporary place and moved there when complete.
    times : numpy.ndarray, shape (N,)
        Time of each observation (s), strictly increasing.
    obs : numpy.ndarray, shape (N, 7)
        Observations (:data:`~rkmpc.core.observation.OBSERVATION_FIELDS`) of the centre of
        gravity; all but ``steer_angle`` finite. ``steer_angle`` goes to the steer topic where finite.
    command : numpy.ndarray, shape (N, 2)
        The command sent at each observation, ``[speed (m/s), steer (rad)]``; rows with a
        non-finite value are not recorded (no command was sent).
    config : BagWriteConfig, optional
        Storage, topics, frames and timing; defaults to ``BagWriteConfig()`` (MCAP, F1TENTH topics).

    Returns
    -------
    Path
        The bag written.

    Raises
    ------
    ParameterError
        For arrays of the wrong shape, times not increasing or non-finite odometry.
    FileExistsError
        When ``path`` exists.
    ImportError
        When ``rosbags`` is not installed.
    """
    cfg = config if config is not None else BagWriteConfig()
    path = Path(path)
    times, obs, command = _checked(times, obs, command)
    if cfg.storage == "ros1" and path.suffix != ".bag":
        raise ParameterError(f"write_bag: a ROS 1 bag's name must end in .bag, got {path.name!r}")
    if path.exists():
        raise FileExistsError(f"{path} exists; a bag is never overwritten")
    store = typestore(ros1=cfg.storage == "ros1")
    messages = _messages(store, times, obs, command, cfg)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.") as tmp:
        draft = Path(tmp) / path.name
        _write(draft, store, messages, cfg)
        os.replace(draft, path)
    return path


def _checked(times: Any, obs: Any, command: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(times, dtype=float)
    o = np.asarray(obs, dtype=float)
    c = np.asarray(command, dtype=float)
    n = t.shape[0] if t.ndim == 1 else -1
    if n < 1 or o.shape != (n, len(OBSERVATION_FIELDS)) or c.shape != (n, 2):
        raise ParameterError(
            "write_bag: need times (N,), obs (N, 7) and command (N, 2), N >= 1; "
            f"got {t.shape}, {o.shape}, {c.shape}"
        )
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise ParameterError("write_bag: times must be finite and strictly increasing")
    for name in _REQUIRED:
        column = o[:, OBSERVATION_FIELDS.index(name)]
        if not np.all(np.isfinite(column)):
            row = int(np.flatnonzero(~np.isfinite(column))[0])
            raise ParameterError(f"write_bag: obs.{name} is not finite at row {row} (t = {t[row]} s)")
    return t, o, c


def _messages(
    store: Any, times: np.ndarray, obs: np.ndarray, command: np.ndarray, cfg: BagWriteConfig
) -> list[tuple[int, str, Any]]:
    """``(stamp ns, topic, message)`` of every message, in time order."""
    types = store.types
    ros1 = cfg.storage == "ros1"
    x, y, yaw, speed, yaw_rate, slip, wheel = obs.T
    odom = np.stack([x, y, yaw, speed, speed * np.tan(slip), yaw_rate], axis=1)
    if cfg.odom_frame == "rear-axle" and cfg.lr is not None:
        odom = odometry_at_cog(odom, -cfg.lr)
    start = round(cfg.start_time * _NS)
    delay = round(cfg.command_delay * _NS)
    stamps = [start + round(t * _NS) for t in times]
    seq = iter(range(1 << 62))

    def header(stamp: int, frame: str) -> Any:
        time = types["builtin_interfaces/msg/Time"](sec=stamp // _NS, nanosec=stamp % _NS)
        if ros1:
            return types["std_msgs/msg/Header"](seq=next(seq), stamp=time, frame_id=frame)
        return types["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    out: list[tuple[int, str, Any]] = []
    for k, stamp in enumerate(stamps):
        out.append((stamp, cfg.odom_topic, _odometry(types, header(stamp, cfg.frame_id), odom[k], cfg)))
        if cfg.steer_topic is not None and math.isfinite(wheel[k]):
            out.append((stamp, cfg.steer_topic, types[FLOAT64](data=float(wheel[k]))))
        if np.all(np.isfinite(command[k])):
            drive = types["ackermann_msgs/msg/AckermannDrive"](
                steering_angle=float(command[k, 1]),
                steering_angle_velocity=0.0,
                speed=float(command[k, 0]),
                acceleration=0.0,
                jerk=0.0,
            )
            stamped = types[ACKERMANN_DRIVE_STAMPED](
                header=header(stamp + delay, cfg.child_frame_id), drive=drive
            )
            out.append((stamp + delay, cfg.drive_topic, stamped))
    out.sort(key=lambda item: item[0])
    return out


def _odometry(types: Any, header: Any, row: np.ndarray, cfg: BagWriteConfig) -> Any:
    x, y, yaw, vx, vy, r = (float(v) for v in row)
    vector = types["geometry_msgs/msg/Vector3"]
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw)
        ),
    )
    twist = types["geometry_msgs/msg/Twist"](
        linear=vector(x=vx, y=vy, z=0.0), angular=vector(x=0.0, y=0.0, z=r)
    )
    covariance = np.zeros(36)
    return types[ODOMETRY](
        header=header,
        child_frame_id=cfg.child_frame_id,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=covariance),
    )


def _write(path: Path, store: Any, messages: list[tuple[int, str, Any]], cfg: BagWriteConfig) -> None:
    """Write the messages with ``rosbags``' writer of the configured storage."""
    kinds = {cfg.odom_topic: ODOMETRY, cfg.drive_topic: ACKERMANN_DRIVE_STAMPED}
    if cfg.steer_topic is not None:
        kinds[cfg.steer_topic] = FLOAT64
    serialize: Callable[[Any, str], Any]
    if cfg.storage == "ros1":
        from rosbags.rosbag1 import Writer as Writer1

        writer: Any = Writer1(path)
        serialize = store.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        plugin = StoragePlugin.MCAP if cfg.storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=Writer2.VERSION_LATEST, storage_plugin=plugin)
        serialize = store.serialize_cdr
    with writer:
        connections = {
            topic: writer.add_connection(topic, kind, typestore=store) for topic, kind in kinds.items()
        }
        for stamp, topic, message in messages:
            writer.write(connections[topic], stamp, serialize(message, kinds[topic]))
