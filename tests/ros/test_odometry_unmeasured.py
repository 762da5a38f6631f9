"""Odometry that does not measure the lateral velocity or the yaw rate reads as NaN, never 0 (issue 25).

A real car's VESC odometry publishes ``twist.linear.y = 0``: read as measured, that is a slip angle
of exactly 0 that the slip drift and the state estimator would trust. The conversion imports no
ROS package, so a plain object with the message's fields stands in for ``nav_msgs/msg/Odometry``.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from rkmpc.config.ros import OdometrySettings
from rkmpc.core.errors import ParameterError
from rkmpc.ros.conversions import fill_odometry, observation_from_odometry, quaternion_from_yaw


def odometry(*, vx: float = 2.0, vy: float = 0.0, r: float = 0.4, yaw: float = 0.3) -> SimpleNamespace:
    """An object with the fields of ``nav_msgs/msg/Odometry`` that the conversion reads."""
    qx, qy, qz, qw = quaternion_from_yaw(yaw)
    vector = SimpleNamespace
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=12, nanosec=500_000_000), frame_id="map"),
        child_frame_id="base_link",
        pose=SimpleNamespace(
            pose=SimpleNamespace(
                position=vector(x=1.0, y=-2.0, z=0.0), orientation=vector(x=qx, y=qy, z=qz, w=qw)
            )
        ),
        twist=SimpleNamespace(
            twist=SimpleNamespace(linear=vector(x=vx, y=vy, z=0.0), angular=vector(x=0.0, y=0.0, z=r))
        ),
    )


def test_measured_odometry_gives_the_slip_angle_and_the_yaw_rate():
    obs = observation_from_odometry(odometry(vx=2.0, vy=0.2, r=0.4))
    assert obs.slip_angle == pytest.approx(math.atan2(0.2, 2.0)) and obs.yaw_rate == 0.4
    assert (obs.x, obs.y, obs.speed, obs.time) == (1.0, -2.0, 2.0, 12.5)
    assert obs.yaw == pytest.approx(0.3) and math.isnan(obs.steer_angle)
    # A measured lateral velocity of 0 is a slip angle of 0.
    assert observation_from_odometry(odometry(vy=0.0)).slip_angle == 0.0


def test_without_a_lateral_velocity_the_slip_angle_is_nan_never_0():
    msg = odometry(vx=2.0, vy=0.0, r=0.4)
    obs = observation_from_odometry(msg, lateral_velocity=False)
    assert math.isnan(obs.slip_angle)
    # Everything else is read as before.
    assert obs.yaw_rate == 0.4 and obs.speed == 2.0 and (obs.x, obs.y) == (1.0, -2.0)
    assert math.isnan(observation_from_odometry(odometry(vx=0.0, vy=0.0), lateral_velocity=False).slip_angle)


def test_without_a_yaw_rate_the_yaw_rate_is_nan():
    obs = observation_from_odometry(odometry(r=0.0), yaw_rate=False)
    assert math.isnan(obs.yaw_rate) and obs.slip_angle == 0.0
    both = observation_from_odometry(odometry(), lateral_velocity=False, yaw_rate=False)
    assert math.isnan(both.yaw_rate) and math.isnan(both.slip_angle)
    assert math.isfinite(both.speed) and math.isfinite(both.yaw)


def test_a_late_localisers_pose_is_dated_back_by_its_latency():
    # The node reads the latency from the car's sensor profile (f1tenth-real: 0.03 s); the state
    # estimator then brings the pose forward. Without it the pose counts as current.
    assert math.isnan(observation_from_odometry(odometry()).pose_time)
    obs = observation_from_odometry(odometry(), pose_latency=0.03)
    assert obs.time == 12.5 and obs.pose_time == pytest.approx(12.47)


def test_a_rear_axle_pose_is_still_moved_to_the_centre_of_gravity():
    obs = observation_from_odometry(odometry(yaw=0.0), rear_axle_to_cog=0.145, lateral_velocity=False)
    assert obs.x == pytest.approx(1.145) and obs.y == pytest.approx(-2.0) and math.isnan(obs.slip_angle)


def test_an_unmeasured_slip_written_to_odometry_reads_back_as_unmeasured():
    from rkmpc.core.observation import Observation

    observation = Observation(1.0, 2.0, 0.1, 3.0, math.nan, math.nan, math.nan, 4.0)
    msg = odometry()
    fill_odometry(msg, observation, frame="map", child_frame="base_link")
    # On the wire a NaN is written as 0 (what a VESC publishes) ...
    assert msg.twist.twist.linear.y == 0.0 and msg.twist.twist.angular.z == 0.0
    # ... and the reader that is told so gives NaN again.
    back = observation_from_odometry(msg, lateral_velocity=False, yaw_rate=False)
    assert math.isnan(back.slip_angle) and math.isnan(back.yaw_rate) and back.speed == 3.0


def test_the_odometry_settings_say_what_is_measured():
    settings = OdometrySettings()
    assert settings.lateral_velocity and settings.yaw_rate
    assert not OdometrySettings(lateral_velocity=False).lateral_velocity
    with pytest.raises(ParameterError, match="lateral_velocity must be true or false"):
        OdometrySettings(lateral_velocity=0)  # type: ignore[arg-type]
