"""Every problem a bag can have is a BagError naming the bag, the topic or field and the problem."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rkmpc.core.errors import BagError, InputFileError
from rkmpc.learning.data.bags import BagImportConfig, import_bag, write_bag
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, ODOMETRY, typestore
from rkmpc.vehicle.params import f1tenth

VEHICLE = f1tenth()
N = 200  # odometry every 10 ms for 2 s; a command every 50 ms


def raw_bag(
    path,
    *,
    odom_stamp_ms=None,
    vx=None,
    qw=None,
    drive_speed=None,
    drive_stamp_ms=None,
    empty_topic: str | None = None,
):
    """An MCAP bag written message by message with rosbags: stamps and values as given.

    Odometry of a car driving along x at ``vx`` (1 m/s) received every 10 ms from 1 s on; its
    header stamps default to the receive times. Commands every 50 ms.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = typestore(ros1=False)
    T = store.types
    received = 1000.0 + 10.0 * np.arange(N)
    odom_stamp_ms = received if odom_stamp_ms is None else np.asarray(odom_stamp_ms, float)
    vx = np.ones(N) if vx is None else np.asarray(vx, float)
    qw = np.ones(N) if qw is None else np.asarray(qw, float)
    drive_at = received[::5]
    drive_stamp_ms = drive_at if drive_stamp_ms is None else np.asarray(drive_stamp_ms, float)
    drive_speed = np.ones(len(drive_at)) if drive_speed is None else np.asarray(drive_speed, float)

    def header(ms):
        ns = round(ms * 1e6)
        return T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id="map"
        )

    vec = T["geometry_msgs/msg/Vector3"]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        odom_conn = writer.add_connection("/ego_racecar/odom", ODOMETRY, typestore=store)
        drive_conn = writer.add_connection("/drive", ACKERMANN_DRIVE_STAMPED, typestore=store)
        if empty_topic is not None:
            writer.add_connection(empty_topic, "std_msgs/msg/Float64", typestore=store)
        messages = []
        for k in range(N):
            pose = T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=0.01 * k, y=0.0, z=0.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=qw[k]),
            )
            twist = T["geometry_msgs/msg/Twist"](
                linear=vec(x=vx[k], y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0)
            )
            msg = T[ODOMETRY](
                header=header(odom_stamp_ms[k]),
                child_frame_id="ego_racecar/base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
            )
            messages.append((received[k], odom_conn, store.serialize_cdr(msg, ODOMETRY)))
        for j, at in enumerate(drive_at):
            drive = T["ackermann_msgs/msg/AckermannDrive"](
                steering_angle=0.0,
                steering_angle_velocity=0.0,
                speed=drive_speed[j],
                acceleration=0.0,
                jerk=0.0,
            )
            msg = T[ACKERMANN_DRIVE_STAMPED](header=header(drive_stamp_ms[j]), drive=drive)
            messages.append((at + 0.5, drive_conn, store.serialize_cdr(msg, ACKERMANN_DRIVE_STAMPED)))
        for at, connection, raw in sorted(messages, key=lambda m: m[0]):
            writer.write(connection, round(at * 1e6), raw)
    return path


def _error(path, config: BagImportConfig | None = None) -> BagError:
    with pytest.raises(BagError) as info:
        import_bag(path, VEHICLE, config)
    return info.value


def test_a_hand_written_bag_imports(tmp_path):
    data = import_bag(raw_bag(tmp_path / "ok"), VEHICLE)
    assert len(data) == 39 and np.all(data.command[:, 0] == 1.0)
    np.testing.assert_allclose(data.obs[:, 0], 0.05 * np.arange(39), atol=1e-12)


def test_a_missing_file_or_no_bag(tmp_path):
    err = _error(tmp_path / "nowhere.bag")
    assert isinstance(err, InputFileError) and "nowhere.bag" in str(err) and "file not found" in str(err)
    junk = tmp_path / "junk.bag"
    junk.write_text("not a bag\n")
    assert "junk.bag" in str(_error(junk))
    (tmp_path / "folder").mkdir()
    assert "not a bag" in str(_error(tmp_path / "folder"))
    notes = tmp_path / "notes.txt"
    notes.write_text("hello\n")
    assert "not a bag" in str(_error(notes))
    broken = raw_bag(tmp_path / "broken")
    (mcap,) = broken.glob("*.mcap")
    mcap.write_bytes(mcap.read_bytes()[:200])
    assert "broken" in str(_error(broken))


def test_a_missing_topic_lists_the_topics_of_the_bag(tmp_path):
    err = _error(raw_bag(tmp_path / "b"), BagImportConfig(odom_topic="/car_state/odom"))
    assert err.topic == "/car_state/odom"
    assert "/ego_racecar/odom (nav_msgs/msg/Odometry, 200)" in str(err)
    assert "/drive (ackermann_msgs/msg/AckermannDriveStamped, 40)" in str(err)


def test_a_wrong_message_type(tmp_path):
    path = raw_bag(tmp_path / "b")
    err = _error(path, BagImportConfig(odom_topic="/drive", drive_topic="/ego_racecar/odom"))
    assert (
        err.topic == "/drive"
        and "ackermann_msgs/msg/AckermannDriveStamped, expected nav_msgs/msg/Odometry" in str(err)
    )
    err = _error(raw_bag(tmp_path / "c", empty_topic="/steer"), BagImportConfig(drive_topic="/steer"))
    assert err.topic == "/steer" and "std_msgs/msg/Float64, expected ackermann_msgs" in str(err)


def test_a_topic_without_messages(tmp_path):
    err = _error(raw_bag(tmp_path / "b", empty_topic="/steer"), BagImportConfig(steer_topic="/steer"))
    assert err.topic == "/steer" and "no messages" in str(err)


def test_too_little_data(tmp_path):
    err = _error(raw_bag(tmp_path / "b"), BagImportConfig(min_samples=40))
    assert "too little data: 39 transitions" in str(err) and "need at least 40" in str(err)
    # Odometry slower than the gap: every message is a stretch of its own.
    err = _error(raw_bag(tmp_path / "c"), BagImportConfig(max_gap=0.005))
    assert "0 transitions" in str(err) and "one every 0.01 s" in str(err)


def test_unsorted_stamps(tmp_path):
    stamps = 1000.0 + 10.0 * np.arange(N)
    stamps[[50, 51]] = stamps[[51, 50]]
    err = _error(raw_bag(tmp_path / "b", odom_stamp_ms=stamps))
    assert err.topic == "/ego_racecar/odom" and err.message_field == "header.stamp"
    assert "stamps go backwards at messages 50 and 51" in str(err)


def test_duplicated_stamps_and_the_receive_time(tmp_path):
    path = raw_bag(tmp_path / "b", odom_stamp_ms=np.zeros(N))  # a driver that leaves the stamps empty
    err = _error(path)
    assert "duplicated stamp at messages 0 and 1" in str(err) and "receive time" in str(err)
    drive_dup = raw_bag(tmp_path / "c", drive_stamp_ms=np.repeat(1000.0 + 100 * np.arange(20), 2))
    assert _error(drive_dup).topic == "/drive"
    data = import_bag(path, VEHICLE, BagImportConfig(stamps="receive"))
    # The grid starts at the first command's receive time, 0.5 ms after an odometry message.
    assert len(data) == 39 and data.metadata["stamps"] == "receive"
    np.testing.assert_allclose(data.obs[:, 0], 0.0005 + 0.05 * np.arange(39), atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "topic", "field", "message"),
    [
        (
            {"vx": np.where(np.arange(N) == 5, math.nan, 1.0)},
            "/ego_racecar/odom",
            "twist.twist.linear.x",
            "message 5",
        ),
        (
            {"qw": np.where(np.arange(N) == 7, 0.0, 1.0)},
            "/ego_racecar/odom",
            "pose.pose.orientation",
            "quaternion",
        ),
        (
            {"drive_speed": np.where(np.arange(40) == 3, math.inf, 1.0)},
            "/drive",
            "drive.speed",
            "inf at message 3",
        ),
    ],
)
def test_non_finite_values(tmp_path, kwargs, topic, field, message):
    err = _error(raw_bag(tmp_path / "b", **kwargs))
    assert (err.topic, err.message_field) == (topic, field)
    assert message in str(err) and str(tmp_path / "b") in str(err)


def test_the_bag_error_reads_well():
    err = BagError("/data/run", "stamps go backwards", "/drive", "header.stamp")
    assert str(err) == "/data/run [/drive, header.stamp]: stamps go backwards"
    assert str(BagError("/data/run", "file not found")) == "/data/run: file not found"


def test_writing_where_a_bag_is_refused(tmp_path):
    path = raw_bag(tmp_path / "b")
    with pytest.raises(FileExistsError):
        write_bag(path, np.zeros(1), np.zeros((1, 7)), np.zeros((1, 2)))
