"""What ``rkmpc node`` decides each period, without ROS: safety, latency compensation, conversions.

The ROS node only moves messages to and from :class:`rkmpc.ros.driver.CarDriver`; these tests
drive it directly with made-up odometry and a scripted controller.
"""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.config.ros import LatencySettings, RosSettings, SafetySettings, Topics
from rkmpc.core.observation import Command, Observation
from rkmpc.ros.conversions import (
    command_from_drive,
    fill_drive,
    fill_odometry,
    observation_from_odometry,
    quaternion_from_yaw,
    seconds_of,
    set_stamp,
    yaw_from_quaternion,
)
from rkmpc.ros.driver import CarDriver
from rkmpc.ros.latency import CommandHistory, propagate
from rkmpc.ros.record import summarise, write_record
from rkmpc.vehicle.kinematic import kinematic_step
from scripted_controller import Scripted


@pytest.fixture
def driver_for(builtin_scenario):
    def make(config: RosSettings | None = None) -> tuple[CarDriver, Scripted]:
        controller = Scripted()
        sc = builtin_scenario
        return CarDriver(controller, sc.reference, sc.vehicle, config or RosSettings()), controller

    return make


def on_path(scenario, s: float, offset: float = 0.0, t: float = 0.0) -> Observation:
    path = scenario.reference.path
    x, y = path.position(s)
    heading = float(path.heading(s))
    return Observation(
        x=float(x) - offset * math.sin(heading),
        y=float(y) + offset * math.cos(heading),
        yaw=heading,
        speed=2.0,
        time=t,
    )


def test_waiting_running_timeout_and_back(driver_for, builtin_scenario):
    driver, controller = driver_for()
    first = driver.step(0.0, 0.0)
    assert first.state == "waiting" and first.command == Command(0.0, 0.0)
    driver.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    running = driver.step(0.05, 0.05)
    assert running.state == "running" and running.command == controller.command and running.fresh
    again = driver.step(0.10, 0.10)
    assert again.state == "running" and not again.fresh  # the same odometry, 0.1 s old
    stale = driver.step(0.6, 0.6)  # no odometry for 0.6 s > 0.5 s
    assert stale.state == "no_odometry" and stale.stop
    assert stale.command == Command(0.0, controller.command.steer)  # speed 0, the wheel held
    assert len(controller.seen) == 2  # the controller did not run on the stale odometry
    driver.on_odometry(on_path(builtin_scenario, 2.0), 0.7, 0.7)
    assert driver.step(0.7, 0.7).state == "running"
    assert driver.safety.counts == {"waiting": 1, "running": 3, "no_odometry": 1}


def test_a_timers_step_dates_the_odometry_at_the_step_and_the_pose_at_its_own_time(
    driver_for, builtin_scenario
):
    # Real time: the odometry (stamp 10.0 on the car's clock) arrived at 3.000 s wall and the timer
    # steps at 3.017 s: a state estimator in front must predict 17 ms on, not plan from the stamp.
    driver, controller = driver_for()
    odometry = on_path(builtin_scenario, 1.0, t=10.0)
    driver.on_odometry(odometry, 3.0, 3.0)
    driver.step(3.017, 3.017)
    seen = controller.seen[-1]
    assert seen.time == pytest.approx(10.017) and seen.pose_time == 10.0
    assert (seen.x, seen.y, seen.yaw, seen.speed) == (odometry.x, odometry.y, odometry.yaw, odometry.speed)
    # A late localiser's pose keeps its own, older time.
    driver.on_odometry(replace(odometry, time=10.05, pose_time=10.02), 3.05, 3.05)
    driver.step(3.06, 3.06)
    assert controller.seen[-1].time == pytest.approx(10.06) and controller.seen[-1].pose_time == 10.02
    # Lock-step (the step at the odometry's own time): as it came.
    driver.on_odometry(replace(odometry, time=10.1), 10.1, 3.1)
    driver.step(10.1, 3.1)
    assert controller.seen[-1] == replace(odometry, time=10.1)


def test_a_too_large_error_stops_the_car_and_latches(driver_for, builtin_scenario):
    driver, _ = driver_for(RosSettings(safety=SafetySettings(max_lateral_error=0.5)))
    driver.on_odometry(on_path(builtin_scenario, 1.0, offset=0.8), 0.0, 0.0)
    decision = driver.step(0.0, 0.0)
    assert decision.state == "tracking_error" and decision.command.speed == 0.0
    assert decision.lateral_error_m == pytest.approx(0.8, abs=1e-6)
    driver.on_odometry(on_path(builtin_scenario, 1.2), 0.05, 0.05)
    assert driver.step(0.05, 0.05).state == "tracking_error"  # latched
    unlatched, _ = driver_for(RosSettings(safety=SafetySettings(max_lateral_error=0.5, latch=False)))
    unlatched.on_odometry(on_path(builtin_scenario, 1.0, offset=0.8), 0.0, 0.0)
    assert unlatched.step(0.0, 0.0).state == "tracking_error"
    unlatched.on_odometry(on_path(builtin_scenario, 1.2), 0.05, 0.05)
    assert unlatched.step(0.05, 0.05).state == "running"
    heading, _ = driver_for(RosSettings(safety=SafetySettings(max_heading_error=0.3)))
    turned = on_path(builtin_scenario, 1.0)
    heading.on_odometry(replace(turned, yaw=turned.yaw + 0.5), 0.0, 0.0)
    assert heading.step(0.0, 0.0).state == "tracking_error"


def test_a_failing_controller_stops_the_car_is_counted_and_tried_again(driver_for, builtin_scenario):
    driver, controller = driver_for()
    driver.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    assert driver.step(0.0, 0.0).state == "running"
    controller.fail = True
    failed = driver.step(0.05, 0.05)
    assert failed.state == "controller_error" and failed.command == Command(0.0, 0.1)
    assert "solver exploded" in failed.message and driver.controller_errors == 1
    controller.fail = False
    controller.command = Command(math.nan, 0.2)
    nan = driver.step(0.10, 0.10)
    assert nan.state == "nonfinite_command" and nan.command == Command(0.0, 0.1)
    assert driver.nonfinite_commands == 1
    controller.command = Command(9.0, 0.2)
    clipped, _ = driver_for(RosSettings(safety=SafetySettings(max_speed=3.0)))
    clipped.controller = controller
    clipped.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    assert clipped.step(0.0, 0.0).command == Command(3.0, 0.2)
    assert driver.step(0.15, 0.15).state == "running"


def test_watchdog_and_shutdown(driver_for, builtin_scenario):
    driver, _ = driver_for()
    assert driver.watchdog(0.0, 0.0) is None  # nothing to guard before the first odometry
    driver.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    driver.step(0.0, 0.0)
    assert driver.watchdog(0.4, 0.4) is None
    stop = driver.watchdog(0.6, 0.6)
    assert stop is not None and stop.state == "no_odometry" and stop.command.speed == 0.0
    final = driver.shutdown(0.7, 0.7)
    assert final.state == "shutdown" and final.command == Command(0.0, 0.1)
    assert [d.state for d in driver.records] == ["running", "no_odometry", "shutdown"]


def test_lock_step_waits_for_the_wheel_angle_of_the_same_period(driver_for, builtin_scenario):
    driver, controller = driver_for(RosSettings(trigger="odometry", topics=Topics(steering="/steer")))
    driver.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    assert not driver.answerable()
    driver.on_steering(0.05)
    assert driver.answerable()
    driver.step(0.0, 0.0)
    assert controller.seen[-1].steer_angle == 0.05
    assert not driver.answerable()  # answered; the next period needs both again
    driver.on_steering(0.07)
    assert not driver.answerable()
    driver.on_odometry(on_path(builtin_scenario, 1.2), 0.05, 0.05)
    assert driver.answerable()


def test_wheel_angle_estimated_from_the_commands(driver_for, builtin_scenario):
    driver, controller = driver_for(RosSettings(steering_estimate=True))
    driver.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    driver.step(0.0, 0.0)
    driver.step(0.05, 0.05)
    first, second = (o.steer_angle for o in controller.seen)
    assert first == 0.0 and 0.0 < second < controller.command.steer  # the servo lags the command


def test_hooks_see_every_decision_and_the_record_files(driver_for, builtin_scenario, tmp_path):
    driver, _ = driver_for()
    seen = []
    driver.hooks.append(seen.append)
    driver.on_odometry(on_path(builtin_scenario, 1.0), 0.0, 0.0)
    driver.step(0.01, 0.01)
    driver.shutdown(0.02, 0.02)
    assert [d.state for d in seen] == ["running", "shutdown"]
    summary = summarise(driver.records)
    assert summary["by_state"] == {"running": 1, "shutdown": 1}
    # From the odometry's arrival to the command: its age when the decision began, plus the step.
    step = driver.records[0].solve_time_s
    assert summary["odometry_to_command_ms"]["median"] == pytest.approx(1e3 * (0.01 + step))
    write_record(tmp_path, driver.records, {"controller": "scripted"})
    lines = (tmp_path / "node_log.csv").read_text().splitlines()
    assert len(lines) == 3 and lines[0].startswith("time,wall,state,speed,steer")
    assert '"controller": "scripted"' in (tmp_path / "node_summary.json").read_text()


# -- latency compensation ------------------------------------------------------------------------


def test_propagation_with_no_latency_is_the_observation():
    obs = Observation(1.0, 2.0, 0.3, 2.0, time=5.0)
    assert propagate(obs, CommandHistory(1.0), 5.0, 5.0, odometry=0.0, actuation=0.0, wheelbase=0.3) == obs


def test_propagation_uses_the_commands_that_act_in_the_window():
    """A 50 ms actuation delay: until the next command acts, the car follows the one sent 50 ms ago."""
    history = CommandHistory(1.0)
    history.add(0.00, Command(2.0, 0.2))
    history.add(0.05, Command(2.0, -0.1))
    obs = Observation(0.0, 0.0, 0.0, 2.0, time=0.05)
    # At t = 0.05 the command sent at 0.00 acts until 0.10, when the one sent now (0.05) takes over.
    out = propagate(obs, history, 0.05, 0.05, odometry=0.0, actuation=0.05, wheelbase=0.3)
    expected = kinematic_step([0.0, 0.0, 0.0], [2.0, 0.2], 0.3, 0.05)
    assert np.allclose([out.x, out.y, out.yaw], expected) and out.time == pytest.approx(0.10)
    # With an odometry 20 ms old as well, the window starts at 0.03 (the command sent at 0.00 acts
    # from 0.05; before, nothing known had been sent: the measured wheel angle, 0 here, acts).
    late = propagate(obs, history, 0.05, 0.05, odometry=0.02, actuation=0.05, wheelbase=0.3)
    state = kinematic_step([0.0, 0.0, 0.0], [2.0, 0.0], 0.3, 0.02)
    state = kinematic_step(state, [2.0, 0.2], 0.3, 0.05)
    assert np.allclose([late.x, late.y, late.yaw], state)
    # A late localiser's pose, once moved, is as current as its new time: an estimator in front
    # must not bring it forward over the localiser's latency a second time.
    moved = propagate(
        replace(obs, pose_time=0.02), history, 0.05, 0.05, odometry=0.0, actuation=0.05, wheelbase=0.3
    )
    assert moved.time == pytest.approx(0.10) and math.isnan(moved.pose_time)
    # ... and it is moved from its own time, 30 ms before the odometry's: 0.02 -> 0.10.
    state = kinematic_step([0.0, 0.0, 0.0], [2.0, 0.0], 0.3, 0.03)
    state = kinematic_step(state, [2.0, 0.2], 0.3, 0.05)
    assert np.allclose([moved.x, moved.y, moved.yaw], state)


def test_the_node_compensates_when_asked(driver_for, builtin_scenario):
    config = RosSettings(latency=LatencySettings(compensate=True, actuation=0.1))
    driver, controller = driver_for(config)
    obs = on_path(builtin_scenario, 1.0)
    driver.on_odometry(obs, 0.0, 0.0)
    driver.step(0.0, 0.0)
    moved = controller.seen[0]
    assert moved.time == pytest.approx(0.1)
    assert math.hypot(moved.x - obs.x, moved.y - obs.y) == pytest.approx(0.2, rel=1e-3)  # 2 m/s, 0.1 s
    assert driver.records[0].observation == obs  # the record keeps what was received


# -- conversions ---------------------------------------------------------------------------------


def odometry_message() -> SimpleNamespace:
    v3 = lambda: SimpleNamespace(x=0.0, y=0.0, z=0.0)  # noqa: E731
    return SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=0, nanosec=0), frame_id=""),
        child_frame_id="",
        pose=SimpleNamespace(
            pose=SimpleNamespace(position=v3(), orientation=SimpleNamespace(x=0, y=0, z=0, w=1))
        ),
        twist=SimpleNamespace(twist=SimpleNamespace(linear=v3(), angular=v3())),
    )


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5, math.pi - 1e-9])
def test_quaternions(yaw):
    assert yaw_from_quaternion(*quaternion_from_yaw(yaw)) == pytest.approx(yaw)


def test_odometry_round_trip_and_rear_axle():
    obs = Observation(1.0, -2.0, 0.4, 3.0, yaw_rate=0.5, slip_angle=0.05, steer_angle=math.nan, time=12.25)
    msg = odometry_message()
    fill_odometry(msg, obs, frame="map", child_frame="ego_racecar/base_link")
    set_stamp(msg.header.stamp, obs.time)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 250_000_000)
    assert seconds_of(msg.header.stamp) == 12.25
    back = observation_from_odometry(msg)
    assert back.x == 1.0 and back.y == -2.0 and back.yaw == pytest.approx(0.4)
    assert back.speed == 3.0 and back.yaw_rate == 0.5 and back.slip_angle == pytest.approx(0.05)
    assert math.isnan(back.steer_angle) and back.time == 12.25
    moved = observation_from_odometry(msg, rear_axle_to_cog=0.17, steer=0.1)
    assert moved.x == pytest.approx(1.0 + 0.17 * math.cos(0.4)) and moved.steer_angle == 0.1
    drive = SimpleNamespace(
        header=SimpleNamespace(frame_id=""), drive=SimpleNamespace(speed=0.0, steering_angle=0.0)
    )
    fill_drive(drive, Command(2.5, -0.2), frame="base_link")
    assert command_from_drive(drive) == Command(2.5, -0.2) and drive.header.frame_id == "base_link"
