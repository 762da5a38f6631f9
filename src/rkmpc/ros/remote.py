"""A controller on the far side of ROS 2, for the simulated car's closed loop.

``rkmpc sim-node`` runs the project's own closed loop (:func:`rkmpc.sim.closed_loop.simulate`:
the start, the lap count, the off-track check, the log) with a :class:`RemoteController` in the
controller's seat: its :meth:`~RemoteController.step` publishes the car's odometry (and its
wheel angle, where asked) and returns the command that came back on the drive topic.

Real time: each step waits for the wall clock to reach the car's time, publishes the odometry at
its rate and returns the newest command (zero-order hold). Lock-step: each step publishes the
odometry and waits for the command stamped with the odometry's stamp, so the run does not depend
on how busy the machine is; the step's time in the log is then the round trip odometry -> command.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from ackermann_msgs.msg import AckermannDriveStamped
from nav_msgs.msg import Odometry
from rclpy.executors import Executor
from rclpy.node import Node
from std_msgs.msg import Float64

from rkmpc.control.base import Controller, StepInfo
from rkmpc.core.observation import Command, Observation
from rkmpc.ros.conversions import command_from_drive, fill_odometry, set_stamp
from rkmpc.ros.sim_config import SimNodeConfig

__all__ = ["RemoteController"]

#: Lock-step: the odometry is published again if no answer came within this (wall-clock s).
_REPUBLISH_S = 1.0
#: Real time: the odometry is published this often (s) while waiting for the first command.
_WAITING_PUBLISH_S = 0.1


class RemoteController(Controller):
    """The controller seat of the simulated loop, filled over ROS 2.

    Parameters
    ----------
    node : Node
        The simulated car's node (publishers and subscription are made on it).
    executor : Executor
        Spun while waiting, so the drive commands arrive.
    config : SimNodeConfig
        Clock mode, rates, topics, frames and time-outs.
    interrupted : callable
        True once the user asked to stop (Ctrl-C).
    """

    name = "ros"

    def __init__(
        self, node: Node, executor: Executor, config: SimNodeConfig, interrupted: Callable[[], bool]
    ) -> None:
        super().__init__()
        self.node = node
        self.executor = executor
        self.config = config
        self.interrupted = interrupted
        self.lockstep = config.clock == "lockstep"
        self.dt = config.period if self.lockstep else config.physics_dt
        self._odometry = node.create_publisher(Odometry, config.odometry_topic, 10)
        self._steering = (
            node.create_publisher(Float64, config.steering_topic, 10) if config.steering_topic else None
        )
        node.create_subscription(AckermannDriveStamped, config.drive_topic, self._on_drive, 10)
        #: Why the run must end (no answer, interrupted); None while it goes on.
        self.abort: str | None = None
        self.received = 0
        self.ignored = 0
        self.published = 0
        self._latest: Command | None = None
        self._pending: tuple[int, int] | None = None
        self._answer: Command | None = None
        self._started = False
        self._wall0 = 0.0
        self._steps = 0

    def stop_reason(self) -> str | None:
        """Why the run must end now, or None (for :class:`rkmpc.ros.sim_plant.PhysicsPlant`)."""
        if self.abort is None and self.interrupted():
            self.abort = "interrupted"
        return self.abort

    def step(self, observation: Observation) -> Command:
        command = super().step(observation)
        if not self.lockstep:  # the step mostly waited for the wall clock: not a figure of the loop
            self.info = StepInfo(status=self.info.status, solve_time_s=math.nan)
        return command

    def _reset(self) -> None:
        self._pending = None
        self._answer = None

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        hold = self._latest if self._latest is not None else Command(observation.speed, 0.0)
        if self.stop_reason():
            return hold, "ok", ""
        command = self._lockstep(observation) if self.lockstep else self._realtime(observation)
        return (command if command is not None else hold), "ok", ""

    # -- real time ------------------------------------------------------------------------------

    def _realtime(self, observation: Observation) -> Command | None:
        if not self._started:
            self._wait_for_first_command(observation)
            self._wall0 = time.monotonic() - observation.time
            self._started = True
        while (remaining := self._wall0 + observation.time - time.monotonic()) > 0.0:
            if self.stop_reason():
                return None
            self.executor.spin_once(timeout_sec=remaining)
        if self._steps % self.config.odometry_every == 0:
            self._publish(observation, None)
        self._steps += 1
        return self._latest

    def _wait_for_first_command(self, observation: Observation) -> None:
        limit = self.config.startup_timeout
        deadline = math.inf if limit is None else time.monotonic() + limit
        next_publish = 0.0
        self.node.get_logger().info("waiting for the first drive command")
        while self._latest is None:
            now = time.monotonic()
            if self.stop_reason():
                return
            if now > deadline:
                self.abort = f"no drive command within {limit} s"
                return
            if now >= next_publish:
                self._publish(observation, None)
                next_publish = now + _WAITING_PUBLISH_S
            self.executor.spin_once(timeout_sec=0.02)
        self.node.get_logger().info("first drive command received: driving")

    # -- lock-step ------------------------------------------------------------------------------

    def _lockstep(self, observation: Observation) -> Command | None:
        first = not self._started
        self._started = True
        if first:
            self._wait_for_peers()
        stamp = self._publish(observation, observation.time)
        self._pending = (stamp.sec, stamp.nanosec)
        self._answer = None
        limit = self.config.startup_timeout if first else self.config.answer_timeout
        start = time.monotonic()
        deadline = math.inf if limit is None else start + limit
        republish = start + _REPUBLISH_S
        while self._answer is None:
            if self.stop_reason():
                return None
            self.executor.spin_once(timeout_sec=0.05)
            now = time.monotonic()
            if now > deadline:
                self.abort = (
                    f"no_controller: no answer to the odometry of t = {observation.time:.3f} s in {limit} s"
                )
                return None
            if now > republish and self._answer is None:
                self._publish(observation, observation.time)
                republish = now + _REPUBLISH_S
        self._pending = None
        return self._answer

    def _wait_for_peers(self) -> None:
        """Until the controller's subscription and publisher are matched (nothing is lost to discovery)."""
        limit = self.config.startup_timeout
        deadline = math.inf if limit is None else time.monotonic() + limit
        self.node.get_logger().info("lock-step: waiting for the controller node")
        while self._odometry.get_subscription_count() == 0 or self._drive_publishers() == 0:
            if self.stop_reason() or time.monotonic() > deadline:
                return
            self.executor.spin_once(timeout_sec=0.05)

    def _drive_publishers(self) -> int:
        return len(self.node.get_publishers_info_by_topic(self.config.drive_topic))

    # -- messages -------------------------------------------------------------------------------

    def _publish(self, observation: Observation, stamp_seconds: float | None) -> Any:
        """Publish the wheel angle, then the odometry; returns the odometry's stamp."""
        msg = Odometry()
        fill_odometry(msg, observation, frame=self.config.frame, child_frame=self.config.child_frame)
        if stamp_seconds is None:
            msg.header.stamp = self.node.get_clock().now().to_msg()
        else:
            set_stamp(msg.header.stamp, stamp_seconds)
        if self._steering is not None:
            self._steering.publish(Float64(data=float(observation.steer_angle)))
        self._odometry.publish(msg)
        self.published += 1
        return msg.header.stamp

    def _on_drive(self, msg: AckermannDriveStamped) -> None:
        command = command_from_drive(msg)
        if not (math.isfinite(command.speed) and math.isfinite(command.steer)):
            self.ignored += 1
            return
        if self.lockstep:
            if self._pending != (msg.header.stamp.sec, msg.header.stamp.nanosec):
                self.ignored += 1  # a watchdog stop, or an answer to an odometry already answered
                return
            self._answer = command
        self.received += 1
        self._latest = command
