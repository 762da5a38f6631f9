"""ackermann_msgs as built by ``make ros`` is upstream's type on the wire: same name, same RIHS01 hash."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from ros_domain import ros_domain_id

pytest.importorskip("rclpy", reason="ROS 2 is not installed (make ros)", exc_type=ImportError)
pytest.importorskip("ackermann_msgs", reason="ackermann_msgs is not built (make ros)", exc_type=ImportError)

pytestmark = pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")

#: The type hashes of upstream ackermann_msgs (ros-drivers/ackermann_msgs, the ROS 2 releases); the
#: generators compute them from the definitions, comments excluded.
UPSTREAM = {
    "ackermann_msgs/msg/AckermannDrive": (
        "RIHS01_acf287a224a947dd1b0b87d6d76cdb73f497b0237b8fc73be2173b2ebbb82c99"
    ),
    "ackermann_msgs/msg/AckermannDriveStamped": (
        "RIHS01_48ca7612a08d3bb72744fd98b71b7cf2ea24c6ad50fa4e1aa0bbad963c90d8cf"
    ),
}
DEFINITIONS = Path(__file__).resolve().parents[2] / "ros" / "ackermann_msgs" / "msg"


def test_the_generated_type_descriptions_carry_upstreams_hashes():
    share = Path(sys.prefix) / "share" / "ackermann_msgs"  # where ros/build_msgs.sh installs it
    for name, expected in UPSTREAM.items():
        described = json.loads((share / "msg" / f"{name.rsplit('/', 1)[1]}.json").read_text())
        hashes = {h["type_name"]: h["hash_string"] for h in described["type_hashes"]}
        assert hashes[name] == expected


def test_rosbags_computes_the_same_hashes_from_the_definitions():
    typesys = pytest.importorskip("rosbags.typesys", reason="rosbags is not installed")
    store = typesys.get_typestore(typesys.Stores.ROS2_KILTED)
    types = {}
    for name in UPSTREAM:
        types.update(
            typesys.get_types_from_msg((DEFINITIONS / f"{name.rsplit('/', 1)[1]}.msg").read_text(), name)
        )
    store.register(types)
    assert {name: store.hash_rihs01(name) for name in UPSTREAM} == UPSTREAM


def test_a_publisher_announces_the_upstream_type(monkeypatch, tmp_path):
    import rclpy
    from ackermann_msgs.msg import AckermannDriveStamped
    from rclpy.signals import SignalHandlerOptions

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_LOG_DIR", str(tmp_path))
    context = rclpy.Context()
    rclpy.init(
        context=context, domain_id=ros_domain_id("hash_probe"), signal_handler_options=SignalHandlerOptions.NO
    )
    try:
        node = rclpy.create_node("hash_probe", context=context)
        node.create_publisher(AckermannDriveStamped, "/drive", 1)
        [info] = node.get_publishers_info_by_topic("/drive")
        assert info.topic_type == "ackermann_msgs/msg/AckermannDriveStamped"
        assert str(info.topic_type_hash) == UPSTREAM["ackermann_msgs/msg/AckermannDriveStamped"]
        msg = AckermannDriveStamped()
        msg.drive.speed, msg.drive.steering_angle = 1.5, -0.25  # float32 fields
        assert (msg.drive.speed, msg.drive.steering_angle) == (1.5, -0.25)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
