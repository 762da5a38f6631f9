"""A bag written message by message (the recorder of ``rkmpc node --record``), without ROS."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rkmpc.core.errors import ParameterError
from rkmpc.learning.data.bags import BagStreamWriter
from rkmpc.learning.data.bags.read import bag_location
from rkmpc.learning.data.bags.types import FLOAT64, ODOMETRY, typestore

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


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_messages_go_to_a_hidden_draft_and_the_bag_appears_when_closed(tmp_path, storage):
    store = typestore(ros1=False)
    path = tmp_path / "run"
    writer = BagStreamWriter(path, TOPICS, storage)
    for k in range(5):
        steer = store.serialize_cdr(store.types[FLOAT64](data=0.1 * k), FLOAT64)
        writer.write("/steer", k * 50_000_000, bytes(steer))
        writer.write("/odom", k * 50_000_000, odometry(store, k * 50_000_000, 0.5 * k))
        assert not path.exists()  # nothing under the final name while recording
    assert [p.name.startswith(".run.") for p in tmp_path.iterdir()] == [True]
    assert writer.close() == path and writer.closed and writer.counts == {"/odom": 5, "/steer": 5}
    assert [p.name for p in tmp_path.iterdir()] == ["run"]
    store_of = bag_location(path)[1]
    assert store_of == f"ros2-{storage}"
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=store) as reader:
        read = [(c.topic, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]
    xs = [m.pose.pose.position.x for topic, _, m in read if topic == "/odom"]
    assert xs == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert [m.data for topic, _, m in read if topic == "/steer"] == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4])


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
    with pytest.raises(ParameterError, match="unknown to the bag's type store"):
        BagStreamWriter(tmp_path / "a", {"/x": "my_msgs/msg/Nothing"})
    writer = BagStreamWriter(tmp_path / "a", TOPICS)
    with pytest.raises(ParameterError, match="not declared"):
        writer.write("/drive", 0, b"")
    writer.discard()
    assert list(tmp_path.iterdir()) == []
