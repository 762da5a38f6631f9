"""A bag written message by message in closed segments (``rkmpc node --record``), without ROS."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rkmpc.core.errors import ParameterError
from rkmpc.learning.data.bags import BagStreamWriter
from rkmpc.learning.data.bags.read import bag_location
from rkmpc.learning.data.bags.stream import RECORDING_KEY, read_metadata
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, FLOAT64, ODOMETRY, typestore

TOPICS = {"/odom": ODOMETRY, "/steer": FLOAT64}


def odometry(store, stamp_ns: int, x: float) -> bytes:
    types = store.types
    msg = types[ODOMETRY](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
            frame_id="map",
        ),
        child_frame_id="base_link",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
                orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
            covariance=np.zeros(36),
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](
                linear=types["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
                angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            ),
            covariance=np.zeros(36),
        ),
    )
    return bytes(store.serialize_cdr(msg, ODOMETRY))


def steer(store, value: float) -> bytes:
    return bytes(store.serialize_cdr(store.types[FLOAT64](data=value), FLOAT64))


def read_back(path) -> list[tuple[str, int, object]]:
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=typestore(ros1=False)) as reader:
        return [(c.topic, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_is_written_in_closed_segments_each_readable_as_it_closes(tmp_path, storage):
    store = typestore(ros1=False)
    path = tmp_path / "run"
    writer = BagStreamWriter(path, TOPICS, storage, segment_s=0.1)
    suffix = ".mcap" if storage == "mcap" else ".db3"
    for k in range(10):  # 50 ms apart: a segment every two steps
        writer.write("/steer", k * 50_000_000, steer(store, 0.1 * k))
        writer.write("/odom", k * 50_000_000, odometry(store, k * 50_000_000, 0.5 * k))
        if k == 6:  # while recording: the closed segments are a bag already
            writer.wait()
            assert writer.segments == 3 and bag_location(path)[1] == f"ros2-{storage}"
            xs = [m.pose.pose.position.x for topic, _, m in read_back(path) if topic == "/odom"]
            assert xs == [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
            assert read_metadata(path)["custom_data"] == {RECORDING_KEY: "unfinished"}
    assert writer.close() == path and writer.closed and writer.counts == {"/odom": 10, "/steer": 10}
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
    assert sorted(p.name for p in path.iterdir()) == ["metadata.yaml"] + [
        f"run_{k}{suffix}" for k in range(5)
    ]
    info = read_metadata(path)
    assert info["custom_data"] == {RECORDING_KEY: "closed"} and info["message_count"] == 20
    assert info["relative_file_paths"] == [f"run_{k}{suffix}" for k in range(5)]
    assert {t["message_count"] for t in info["topics_with_message_count"]} == {10}
    assert info["duration"]["nanoseconds"] == 450_000_000
    read = read_back(path)
    assert [m.pose.pose.position.x for topic, _, m in read if topic == "/odom"] == [
        0.5 * k for k in range(10)
    ]
    assert [m.data for topic, _, m in read if topic == "/steer"] == pytest.approx(
        [0.1 * k for k in range(10)]
    )


KILLED = """
import os, signal, sys
from rkmpc.learning.data.bags import BagStreamWriter
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, ODOMETRY
sys.path.insert(0, {tests!r})
from test_bag_stream import drive, odometry
from rkmpc.learning.data.bags.types import typestore
store = typestore(ros1=False)
topics = {{"/odom": ODOMETRY, "/drive": ACKERMANN_DRIVE_STAMPED}}
writer = BagStreamWriter({path!r}, topics, {storage!r}, segment_s=1.0)
for k in range(70):  # 3.5 s at 20 Hz, then killed: the segment of 3 s to 3.5 s is lost
    writer.write("/odom", k * 50_000_000, odometry(store, k * 50_000_000, 0.1 * k))
    writer.write("/drive", k * 50_000_000, drive(store, k * 50_000_000))
writer.wait()  # as a recorder that lives on: its thread has written what it was given
os.kill(os.getpid(), signal.SIGKILL)
"""


def drive(store, stamp_ns: int) -> bytes:
    types = store.types
    msg = types[ACKERMANN_DRIVE_STAMPED](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
            frame_id="base_link",
        ),
        drive=types["ackermann_msgs/msg/AckermannDrive"](
            steering_angle=0.1, steering_angle_velocity=0.0, speed=2.0, acceleration=0.0, jerk=0.0
        ),
    )
    return bytes(store.serialize_cdr(msg, ACKERMANN_DRIVE_STAMPED))


@pytest.mark.parametrize("storage", ["mcap", pytest.param("sqlite3", marks=pytest.mark.slow)])
def test_a_recording_killed_with_sigkill_imports_up_to_its_last_closed_segment(tmp_path, storage):
    """A recorder killed (``kill -9``) leaves a bag that imports, with a word that it never ended."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    from rkmpc.learning.data.bags import BagImportConfig, import_bag
    from rkmpc.learning.data.bags.read import read_streams
    from rkmpc.vehicle.params import f1tenth

    path = tmp_path / "bag"
    tests = str(Path(__file__).parent)
    src = str(Path(__file__).resolve().parents[2] / "src")
    script = KILLED.format(tests=tests, path=str(path), storage=storage)
    env = {**os.environ, "PYTHONPATH": src}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == -signal.SIGKILL, done.stderr
    config = BagImportConfig(odom_topic="/odom", drive_topic="/drive", min_samples=10)
    streams = read_streams(path, config)
    assert streams.unfinished and len(streams.odom) == len(streams.drive) == 60  # 0 to 2.95 s
    assert streams.odom.values[-1, 0] == pytest.approx(5.9)
    data = import_bag(path, f1tenth(), config)
    assert data.metadata["recording"] == "unfinished" and len(data) >= 55


def test_a_recording_killed_before_its_first_segment_closed_says_so(tmp_path):
    from rkmpc.core.errors import BagError

    store = typestore(ros1=False)
    writer = BagStreamWriter(tmp_path / "bag", TOPICS)
    writer.write("/odom", 0, odometry(store, 0, 0.0))  # then the recorder dies: never closed
    with pytest.raises(BagError, match=r"ended \(killed\?\) before its first segment \(2 s\) was closed"):
        bag_location(tmp_path / "bag")
    writer.discard()


def test_a_bag_is_never_overwritten_and_a_discarded_one_leaves_nothing(tmp_path):
    (tmp_path / "old").mkdir()
    with pytest.raises(FileExistsError, match="never overwritten"):
        BagStreamWriter(tmp_path / "old", TOPICS)
    writer = BagStreamWriter(tmp_path / "new", TOPICS)
    writer.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"]
    with pytest.raises(ParameterError, match="closed"):
        writer.write("/odom", 0, b"")


def test_wrong_settings_are_refused(tmp_path):
    with pytest.raises(ParameterError, match="storage"):
        BagStreamWriter(tmp_path / "a", TOPICS, "ros1")
    with pytest.raises(ParameterError, match="segment_s"):
        BagStreamWriter(tmp_path / "a", TOPICS, segment_s=0.0)
    with pytest.raises(ParameterError, match="unknown to the bag's type store"):
        BagStreamWriter(tmp_path / "a", {"/x": "my_msgs/msg/Nothing"})
    writer = BagStreamWriter(tmp_path / "a", TOPICS)
    with pytest.raises(ParameterError, match="not declared"):
        writer.write("/drive", 0, b"")
    writer.discard()
    assert list(tmp_path.iterdir()) == []
