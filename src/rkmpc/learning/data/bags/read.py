"""Read the odometry, command and steer topics of a bag into time-stamped arrays, checked.

Every problem is a :class:`~rkmpc.core.errors.BagError` naming the bag, the topic, the field and
the problem: a missing file or a file that is no bag, a missing topic (with the topics the bag
has), a wrong message type, a topic without messages, stamps that go backwards or repeat, and
non-finite values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.core.errors import BagError
from rkmpc.learning.data.bags.config import BagImportConfig
from rkmpc.learning.data.bags.stream import DRAFTS, RECORDING_KEY, SEGMENT_S, read_metadata
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, ODOMETRY, STEER_TYPES, typestore

__all__ = ["ODOM_FIELDS", "BagStreams", "Stream", "bag_location", "read_streams"]

#: Columns of the odometry stream: the pose of the child frame in the map frame and its twist in
#: the child frame, ``x, y`` (m), ``yaw`` (rad, in (-pi, pi]), ``vx, vy`` (m/s), ``yaw_rate`` (rad/s).
ODOM_FIELDS = ("x", "y", "yaw", "vx", "vy", "yaw_rate")
_ODOM_SOURCES = (
    "pose.pose.position.x",
    "pose.pose.position.y",
    "pose.pose.orientation",
    "twist.twist.linear.x",
    "twist.twist.linear.y",
    "twist.twist.angular.z",
)
_DRIVE_SOURCES = ("drive.speed", "drive.steering_angle")
_NS = 1_000_000_000


@dataclass(frozen=True, eq=False)
class Stream:
    """The messages of one topic as arrays, in the order the bag holds them.

    Parameters
    ----------
    topic : str
        Topic name.
    stamps : numpy.ndarray, shape (N,), int64
        Time of each message (ns): its header stamp or its receive time.
    values : numpy.ndarray, shape (N, K)
        The values of each message, in SI units, columns named by ``fields``.
    fields : tuple of str
        The message fields the columns come from (for messages).
    """

    topic: str
    stamps: np.ndarray
    values: np.ndarray
    fields: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.stamps.shape[0])


@dataclass(frozen=True, eq=False)
class BagStreams:
    """The topics an import reads from one bag.

    Parameters
    ----------
    path : Path
        The bag as opened (a ``.bag`` file or a ROS 2 bag folder).
    storage : str
        ``"ros1"``, ``"ros2-mcap"`` or ``"ros2-sqlite3"``.
    odom, drive : Stream
        Odometry (columns :data:`ODOM_FIELDS`) and commands (``speed`` m/s, ``steer`` rad).
    steer : Stream or None
        Wheel angle (rad, one column), when a steer topic was asked for.
    frames : tuple of str
        ``(frame_id, child_frame_id)`` of the first odometry message.
    unfinished : bool
        The bag is a recording that never ended (``rkmpc node --record`` killed): it holds what
        was recorded up to its last closed segment (:mod:`~rkmpc.learning.data.bags.stream`).
    """

    path: Path
    storage: str
    odom: Stream
    drive: Stream
    steer: Stream | None
    frames: tuple[str, str]
    unfinished: bool = False


def bag_location(path: str | Path) -> tuple[Path, str]:
    """The path ``rosbags`` opens and the bag's storage (``ros1``, ``ros2-mcap``, ``ros2-sqlite3``).

    A ``.bag`` file is a ROS 1 bag; a folder with a ``metadata.yaml`` a ROS 2 bag (a ``.mcap`` or
    ``.db3`` file inside such a folder stands for the folder).
    """
    path = Path(path)
    if not path.exists():
        raise BagError(path, "file not found")
    if path.is_file() and path.suffix == ".bag":
        return path, "ros1"
    if path.is_file() and path.suffix in (".mcap", ".db3"):
        if not (path.parent / "metadata.yaml").is_file():
            raise BagError(path, "a ROS 2 bag file without its metadata.yaml: give the bag's folder")
        path = path.parent
    if path.is_dir() and (path / "metadata.yaml").is_file():
        kinds = {p.suffix for p in path.iterdir()}
        return path, "ros2-mcap" if ".mcap" in kinds else "ros2-sqlite3" if ".db3" in kinds else "ros2"
    if path.is_dir() and (path / DRAFTS).is_dir():
        raise BagError(
            path,
            f"a recording that ended (killed?) before its first segment ({SEGMENT_S:g} s) was closed: "
            "nothing in it can be read",
        )
    raise BagError(
        path, "not a bag: a ROS 1 bag is a file ending in .bag, a ROS 2 bag a folder with a metadata.yaml"
    )


def read_streams(path: str | Path, config: BagImportConfig) -> BagStreams:
    """Read and check the odometry, drive and (optional) steer topics of a bag.

    Parameters
    ----------
    path : str or Path
        A ROS 1 ``.bag`` file, or a ROS 2 bag folder (sqlite3 or MCAP).
    config : BagImportConfig
        Topics, time base and the steer topic's gain and offset.

    Returns
    -------
    BagStreams

    Raises
    ------
    BagError
        Naming the bag, the topic, the field and the problem.
    ImportError
        When ``rosbags`` is not installed.
    """
    location, storage = bag_location(path)
    unfinished = storage != "ros1" and _recording_state(location) == "unfinished"
    store = typestore(ros1=storage == "ros1")
    from rosbags.highlevel import AnyReader, AnyReaderError

    wanted: dict[str, tuple[str, ...]] = {
        config.odom_topic: (ODOMETRY,),
        config.drive_topic: (ACKERMANN_DRIVE_STAMPED,),
    }
    if config.steer_topic is not None:
        wanted[config.steer_topic] = STEER_TYPES
    rows: dict[str, list[tuple[int, tuple[float, ...]]]] = {topic: [] for topic in wanted}
    frames = ("", "")
    try:
        with AnyReader([location], default_typestore=store) as reader:
            topics = reader.topics
            for topic, types in wanted.items():
                _check_topic(location, topics, topic, types)
            connections = [c for c in reader.connections if c.topic in wanted]
            for connection, received, raw in reader.messages(connections=connections):
                topic = connection.topic
                msg: Any = reader.deserialize(raw, connection.msgtype)
                if topic == config.odom_topic:
                    if not rows[topic]:
                        frames = (str(msg.header.frame_id), str(msg.child_frame_id))
                    row = _odometry(msg)
                elif topic == config.drive_topic:
                    row = (float(msg.drive.speed), float(msg.drive.steering_angle))
                else:
                    row = ((float(msg.data) - config.steer_offset) / config.steer_gain,)
                header = topic != config.steer_topic and config.stamps == "header"
                stamp = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec if header else received
                rows[topic].append((int(stamp), row))
    except BagError:
        raise
    except AnyReaderError as exc:
        raise BagError(location, f"cannot read the bag: {exc}") from None
    except (OSError, ValueError, KeyError) as exc:
        raise BagError(location, f"not a readable bag: {exc}") from None
    header_field = "header.stamp" if config.stamps == "header" else "receive time"
    odom = _stream(location, config.odom_topic, rows, ODOM_FIELDS, _ODOM_SOURCES, header_field)
    drive = _stream(location, config.drive_topic, rows, ("speed", "steer"), _DRIVE_SOURCES, header_field)
    steer = None
    if config.steer_topic is not None:
        steer = _stream(location, config.steer_topic, rows, ("steer_angle",), ("data",), "receive time")
    return BagStreams(
        path=location,
        storage=storage,
        odom=odom,
        drive=drive,
        steer=steer,
        frames=frames,
        unfinished=unfinished,
    )


def _recording_state(location: Path) -> str | None:
    """The state a recorder left in a ROS 2 bag's ``custom_data`` (``unfinished``, ``closed``), if any."""
    try:
        custom = read_metadata(location).get("custom_data")
    except Exception:  # unreadable metadata: the reader says why
        return None
    state = custom.get(RECORDING_KEY) if isinstance(custom, dict) else None
    return state if isinstance(state, str) else None


def _check_topic(path: Path, topics: dict[str, Any], topic: str, types: tuple[str, ...]) -> None:
    if topic not in topics:
        have = ", ".join(f"{name} ({info.msgtype}, {info.msgcount})" for name, info in sorted(topics.items()))
        raise BagError(path, f"no such topic; the bag has: {have or 'no topics'}", topic)
    msgtype = topics[topic].msgtype
    if msgtype not in types:
        expected = " or ".join(types)
        raise BagError(path, f"messages of type {msgtype}, expected {expected}", topic)
    if topics[topic].msgcount == 0:
        raise BagError(path, "the topic has no messages", topic)


def _odometry(msg: Any) -> tuple[float, ...]:
    """``x, y, yaw, vx, vy, yaw_rate`` of an Odometry message; yaw NaN for a degenerate quaternion."""
    q = msg.pose.pose.orientation
    qx, qy, qz, qw = float(q.x), float(q.y), float(q.z), float(q.w)
    norm2 = qx * qx + qy * qy + qz * qz + qw * qw
    if math.isfinite(norm2) and norm2 > 1e-12:
        yaw = math.atan2(2.0 * (qw * qz + qx * qy), norm2 - 2.0 * (qy * qy + qz * qz))
    else:
        yaw = math.nan
    position, twist = msg.pose.pose.position, msg.twist.twist
    return (
        float(position.x),
        float(position.y),
        yaw,
        float(twist.linear.x),
        float(twist.linear.y),
        float(twist.angular.z),
    )


def _stream(
    path: Path,
    topic: str,
    rows: dict[str, list[tuple[int, tuple[float, ...]]]],
    fields: tuple[str, ...],
    sources: tuple[str, ...],
    stamp_field: str,
) -> Stream:
    """The rows of a topic as a checked :class:`Stream`: stamps strictly increasing, values finite."""
    stamps = np.array([stamp for stamp, _ in rows[topic]], dtype=np.int64)
    values = np.array([row for _, row in rows[topic]], dtype=float).reshape(len(stamps), len(fields))
    steps = np.diff(stamps)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        at = f"messages {i} and {i + 1} (t = {stamps[i] / _NS:.9f} s and {stamps[i + 1] / _NS:.9f} s)"
        if steps[i] == 0:
            hint = (
                "; stamps not filled in? import with the receive time"
                if stamp_field != "receive time"
                else ""
            )
            raise BagError(path, f"duplicated stamp at {at}{hint}", topic, stamp_field)
        raise BagError(
            path, f"stamps go backwards at {at}: the messages must be in time order", topic, stamp_field
        )
    bad = ~np.isfinite(values)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        problem = (
            "a zero or non-finite quaternion" if sources[j] == "pose.pose.orientation" else f"{values[i, j]}"
        )
        raise BagError(
            path,
            f"{problem} at message {i} (t = {stamps[i] / _NS:.9f} s): values must be finite",
            topic,
            sources[j],
        )
    return Stream(topic=topic, stamps=stamps, values=values, fields=fields)
