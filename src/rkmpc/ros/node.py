"""``rkmpc node``: any controller of the registry driving a car over ROS 2.

In: ``nav_msgs/msg/Odometry`` (``/ego_racecar/odom``) and, where the car measures it, the front
wheel angle (``std_msgs/msg/Float64``). Out: ``ackermann_msgs/msg/AckermannDriveStamped``
(``/drive``) at a fixed rate (20 Hz by default) and ``diagnostic_msgs/msg/DiagnosticArray``
(``/diagnostics``: the safety state, the controller's step time, fall-backs, errors, lateral and
heading error, the odometry's age). Settings: the car file every command reads, its ``[ros]``
section overridden by ROS parameters (:mod:`rkmpc.ros.config`); the track, controller and model
from the command line (:class:`rkmpc.ros.config.NodeTask`). What happens each period, and when the car
is stopped, is
:class:`rkmpc.ros.driver.CarDriver`'s; this module only moves messages.

Ctrl-C (or SIGTERM) ends the node with a final stop command. :meth:`ControllerNode.add_recorder`
hands every message in and out to a recorder; ``--record`` (``record.bag``) writes them to a bag
(:mod:`rkmpc.ros.bag_record`), closed after the final stop, and ``--out`` writes what the node
decided (:mod:`rkmpc.ros.record`) when it ends.

In lock-step (``trigger: odometry``) the node's clock is the car's: the commands that answer no
odometry (a watchdog stop, the final stop) and the diagnostics are stamped with the last
odometry's stamp advanced by the wall time since it arrived.
"""

from __future__ import annotations

import math
import signal
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import rclpy
from ackermann_msgs.msg import AckermannDriveStamped
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64

from rkmpc.config.car import CarConfig
from rkmpc.core.errors import ParameterError
from rkmpc.learning.io import load_model
from rkmpc.learning.recipes import recipe_for
from rkmpc.ros.bag_record import BagRecorder, bag_path
from rkmpc.ros.config import NodeTask, flatten, load_node_car
from rkmpc.ros.conversions import fill_drive, observation_from_odometry, seconds_of, set_stamp
from rkmpc.ros.driver import CarDriver, Decision
from rkmpc.ros.record import write_record
from rkmpc.sim.build import build_controller
from rkmpc.sim.scenario import Scenario

__all__ = ["ControllerNode", "make_driver", "run_node"]

Recorder = Callable[[str, Any, int], None]

#: Parameters every rclpy node declares itself; any other parameter must be a key of the car's file.
_ROS_OWN_PARAMETERS = ("use_sim_time", "start_type_description_service")


def make_driver(car: CarConfig, task: NodeTask) -> CarDriver:
    """The task's controller on its track and car, model loaded and checked, in a :class:`CarDriver`.

    The controller is built as every command builds it (:func:`rkmpc.sim.build.build_controller`),
    planning with the node's period (``[ros] rate_hz``).

    Raises
    ------
    ParameterError
        For a learned controller without a model file, or a model given to one that takes none.
    ContractError
        For a model made with another car, period or track scale (unless ``allow_mismatch``).
    """
    ros = car.ros
    scenario = Scenario.from_car(car, task.track, scale=task.scale, raceline=task.raceline, dt=ros.period)
    recipe = recipe_for(task.controller)
    model = None
    if recipe is not None:
        if task.model is None:
            raise ParameterError(
                f"controller {task.controller!r} needs --model (a {recipe.kind!r} model file)"
            )
        model = load_model(task.model, recipe.kind)
    elif task.model is not None:
        raise ParameterError(f"controller {task.controller!r} takes no model, but --model is given")
    controller = build_controller(task.controller, scenario, model, allow_mismatch=task.allow_mismatch)
    return CarDriver(controller, scenario.reference, scenario.vehicle, ros)


class ControllerNode(Node):
    """The node: subscriptions, publishers and timers around a :class:`CarDriver`.

    Parameters
    ----------
    car : CarConfig or Path
        The car, or its file (TOML, or YAML); ROS parameter overrides of its ``[ros]`` keys are applied.
    task : NodeTask
        What it drives (track, controller, model).
    context : rclpy.context.Context, optional
        The ROS context (the default one when None).
    overrides : mapping of str to object, optional
        ``[ros]`` keys (dotted names) set after the ROS parameters (the command line's ``--record``).
    """

    def __init__(
        self,
        car: CarConfig | Path,
        task: NodeTask,
        *,
        context: Any = None,
        overrides: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__("rkmpc_node", context=context, automatically_declare_parameters_from_overrides=True)
        settings = {
            name: param.value
            for name, param in self.get_parameters_by_prefix("").items()
            if name not in _ROS_OWN_PARAMETERS and not name.startswith("qos_overrides.")
        }
        settings.update(overrides or {})
        self.car = load_node_car(car, settings)
        self.task = task
        self.config = config = self.car.ros
        for name, value in flatten(config).items():
            if value is not None and not self.has_parameter(name):
                self.declare_parameter(name, value)
        self.driver = make_driver(self.car, task)
        self.recorders: list[Recorder] = []
        self._lr = self.driver.vehicle.lr if config.odometry.pose == "rear_axle" else 0.0
        # The car's localiser (its [sensors] profile) is this late: the odometry's pose is that much
        # older than its stamp, and the state estimator brings it forward (f1tenth-real: 0.03 s).
        self._pose_latency = self.car.sensors.pose_latency
        self._lockstep = config.trigger == "odometry"
        self._answered: tuple[int, int] | None = None
        self._pending_stamp: Any = None
        self._answer_msg: AckermannDriveStamped | None = None
        self._car_clock: tuple[float, float] | None = None  # lock-step: (last stamp, its arrival), s
        self._last_decision: Decision | None = None
        self._state = ""
        self._frame_warned = False
        topics = config.topics
        self._drive = self.create_publisher(AckermannDriveStamped, topics.drive, 10)
        self._diagnostics = self.create_publisher(DiagnosticArray, topics.diagnostics, 10)
        reliability = (
            ReliabilityPolicy.BEST_EFFORT
            if config.odometry.reliability == "best_effort"
            else ReliabilityPolicy.RELIABLE
        )
        # The wheel angle's subscription first: when both messages wait, it is taken first.
        if topics.steering is not None:
            self.create_subscription(Float64, topics.steering, self._on_steering, 10)
        self.create_subscription(
            Odometry, topics.odometry, self._on_odometry, QoSProfile(depth=10, reliability=reliability)
        )
        self.create_timer(config.period, self._on_timer, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"{task.controller} on {task.track} at {config.rate_hz:g} Hz ({config.trigger}); "
            f"odometry {topics.odometry} -> commands {topics.drive}"
        )

    def add_recorder(self, recorder: Recorder) -> None:
        """Call ``recorder(topic, message, receive_or_send_time_ns)`` for every message in and out."""
        self.recorders.append(recorder)

    def close(self) -> Decision:
        """Send the final stop command and wait (1 s at most) until it is delivered."""
        wall = time.monotonic()
        decision = self.driver.shutdown(wall, wall)
        self._publish(decision, self._now())
        self._drive.wait_for_all_acked(Duration(seconds=1.0))
        return decision

    # -- callbacks ------------------------------------------------------------------------------

    def _on_steering(self, msg: Float64) -> None:
        self._record(self.config.topics.steering or "", msg)
        self.driver.on_steering(float(msg.data))
        self._answer()

    def _on_odometry(self, msg: Odometry) -> None:
        key = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        if self._lockstep and key == self._answered and self._answer_msg is not None:
            self._drive.publish(self._answer_msg)  # the car asked again: it missed the answer
            return
        self._record(self.config.topics.odometry, msg)
        wanted = self.config.frames.map
        if wanted is not None and msg.header.frame_id != wanted:
            if not self._frame_warned:
                self.get_logger().warning(
                    f"odometry in frame {msg.header.frame_id!r}, not {wanted!r}: ignored (frames.map)"
                )
                self._frame_warned = True
            return
        reading = self.config.odometry
        observation = observation_from_odometry(
            msg,
            rear_axle_to_cog=self._lr,
            # A car whose sensors measure no side slip has no lateral velocity to read (a VESC's 0).
            lateral_velocity=reading.lateral_velocity and self.car.sensors.measures_slip_angle,
            yaw_rate=reading.yaw_rate,
            pose_latency=self._pose_latency,
        )
        wall = time.monotonic()
        if not self._lockstep:
            self.driver.on_odometry(observation, wall, wall)
            return
        self._car_clock = (seconds_of(msg.header.stamp), wall)
        self._pending_stamp = msg.header.stamp
        self.driver.on_odometry(observation, seconds_of(msg.header.stamp), wall)
        self._answer()

    def _answer(self) -> None:
        """Lock-step: answer the pending odometry once it (and its wheel angle) is in."""
        if not self._lockstep or self._pending_stamp is None or not self.driver.answerable():
            return
        stamp = self._pending_stamp
        decision = self.driver.step(seconds_of(stamp), time.monotonic())
        self._answer_msg = self._publish(decision, stamp)
        self._answered = (stamp.sec, stamp.nanosec)
        self._pending_stamp = None

    def _now(self) -> Any:
        """The stamp of a message sent now: ROS time, or in lock-step the car's clock (the module)."""
        if self._car_clock is None:
            return self.get_clock().now().to_msg()
        stamp, arrived = self._car_clock
        now = Time()
        set_stamp(now, stamp + (time.monotonic() - arrived))
        return now

    def _on_timer(self) -> None:
        wall = time.monotonic()
        now = self._now()
        if self._lockstep:
            decision = self.driver.watchdog(wall, wall)
            if decision is not None:
                self._publish(decision, now)
        else:
            self._publish(self.driver.step(wall, wall), now)
        self._publish_diagnostics(now)

    # -- out ------------------------------------------------------------------------------------

    def _publish(self, decision: Decision, stamp: Any) -> AckermannDriveStamped:
        msg = AckermannDriveStamped()
        fill_drive(msg, decision.command, frame=self.config.frames.drive)
        msg.header.stamp = stamp
        self._drive.publish(msg)
        self._last_decision = decision
        self._record(self.config.topics.drive, msg)
        if decision.state != self._state:
            text = f"{decision.state}" + (
                f": {decision.message}" if decision.message and decision.stop else ""
            )
            if decision.stop:  # one severity per call site (rclpy's rule)
                self.get_logger().warning(f"state {text}")
            else:
                self.get_logger().info(f"state {text}")
            self._state = decision.state
        return msg

    def _publish_diagnostics(self, stamp: Any) -> None:
        d = self._last_decision
        if d is None:
            return
        driver = self.driver
        level = (
            DiagnosticStatus.OK
            if d.state == "running"
            else (DiagnosticStatus.WARN if d.state == "waiting" else DiagnosticStatus.ERROR)
        )
        values: dict[str, Any] = {
            "state": d.state,
            "controller": driver.controller.name,
            "solve_time_ms": 1e3 * d.solve_time_s,
            "controller_status": d.status,
            "fallbacks": driver.controller.fallback_count,
            "controller_errors": driver.controller_errors,
            "nonfinite_commands": driver.nonfinite_commands,
            "stops": sum(n for state, n in driver.safety.counts.items() if state != "running"),
            "lateral_error_m": d.lateral_error_m,
            "heading_error_rad": d.heading_error_rad,
            "odometry_age_s": d.odometry_age_s,
            **driver.controller.diagnostics(),
        }
        status = DiagnosticStatus(
            level=level,
            name="rkmpc node",
            message=d.state + (f": {d.message}" if d.stop and d.message else ""),
            hardware_id=self.car.preset,
            values=[KeyValue(key=k, value=_text(v)) for k, v in values.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = stamp
        self._diagnostics.publish(array)

    def _record(self, topic: str, msg: Any) -> None:
        if self.recorders:
            now = time.time_ns()
            for recorder in self.recorders:
                recorder(topic, msg, now)


def _text(value: Any) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.6g}"
    return str(value)


def run_node(
    car: CarConfig | Path,
    task: NodeTask,
    *,
    out: Path | None = None,
    record: Path | None = None,
    record_storage: str | None = None,
    ros_args: list[str] | None = None,
) -> int:
    """Run the node until Ctrl-C or SIGTERM; then a final stop command, the bag and ``--out`` files.

    ``record`` and ``record_storage`` set ``[ros] record.bag`` and ``record.storage`` of the car's file.
    The bag is created before the node drives (an existing one is an error) and closed after the
    final stop, on Ctrl-C and SIGTERM alike. Returns 0.
    """
    overrides: dict[str, Any] = {}
    if record is not None:
        overrides["record.bag"] = str(record.expanduser().resolve())
    if record_storage is not None:
        overrides["record.storage"] = record_storage
    stop = {"flag": False}

    def on_signal(signum: int, frame: Any) -> None:
        stop["flag"] = True

    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    node: ControllerNode | None = None
    recorder: BagRecorder | None = None
    try:
        node = ControllerNode(car, task, overrides=overrides)
        if node.config.record.bag is not None:
            recorder = BagRecorder(bag_path(node.config.record.bag), node.config)
            node.add_recorder(recorder)
            node.get_logger().info(f"recording to {recorder.path} ({node.config.record.storage})")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop["flag"]:
            executor.spin_once(timeout_sec=0.1)
        node.close()
        node.get_logger().info("stopped: final stop command sent")
        if recorder is not None:
            node.get_logger().info(f"bag written: {recorder.close()} {recorder.counts}")
        if out is not None:
            driver = node.driver
            write_record(
                out,
                driver.records,
                {
                    "config": flatten(node.config),
                    "task": flatten(node.task),
                    "car": node.car.to_json(),
                    "controller_errors": driver.controller_errors,
                    "nonfinite_commands": driver.nonfinite_commands,
                    "fallbacks": driver.controller.fallback_count,
                    "last_error": driver.last_error,
                },
            )
        return 0
    finally:
        if recorder is not None:
            recorder.close()  # what was recorded is kept, also when the node failed
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
