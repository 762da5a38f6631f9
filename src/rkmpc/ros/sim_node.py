"""``rkmpc sim-node``: the project's simulated car as a ROS 2 node, like the F1TENTH simulator's bridge.

Any plant of the project (a vehicle preset's, or a car of the zoo) integrates at 100 Hz,
publishes ``nav_msgs/msg/Odometry`` on ``/ego_racecar/odom`` (frame ``map``, child
``ego_racecar/base_link``) and applies the ``ackermann_msgs/msg/AckermannDriveStamped`` commands
of ``/drive`` (zero-order hold, after an optional actuation delay). The run is the project's own
closed loop (:func:`rkmpc.sim.closed_loop.simulate` with a :class:`~rkmpc.ros.remote.RemoteController`),
so its lap count, errors and log are the in-process run's.

While it drives, a JSON status (time, progress in laps, laps completed) goes out on
``/rkmpc/sim/status`` (``std_msgs/msg/String``, kept for late subscribers); when the laps are
done, the car leaves the track or the user presses Ctrl-C, a final status carries the outcome and
the lap's metrics (:func:`rkmpc.analysis.metrics.lap_metrics`: lateral error, ...), the same
summary is logged, and with ``--out`` written to ``summary.json`` beside the run's ``log.csv``.
Exit status: 0 when the laps were completed, 1 otherwise.
"""

from __future__ import annotations

import json
import math
import signal
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.core.io import write_json_atomic
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.ros.remote import RemoteController
from rkmpc.ros.sim_config import SimNodeConfig
from rkmpc.ros.sim_plant import PhysicsPlant
from rkmpc.sim.closed_loop import SimConfig, SimResult, simulate
from rkmpc.sim.scenario import Scenario

__all__ = ["run_sim_node", "summary_of"]

#: Status messages while driving, at most this often in simulated time (s).
_STATUS_PERIOD_S = 0.1


def run_sim_node(config: SimNodeConfig, *, out: Path | None = None, ros_args: list[str] | None = None) -> int:
    """Drive the simulated car over ROS 2 until its laps are done; returns the exit status."""
    interrupted = {"flag": False}

    def on_signal(signum: int, frame: Any) -> None:
        interrupted["flag"] = True

    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = rclpy.create_node("rkmpc_sim")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        scenario = Scenario.from_car(config.car, config.track, raceline=config.raceline, scale=config.scale)
        status_qos = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        status = node.create_publisher(String, config.status_topic, status_qos)
        remote = RemoteController(node, executor, config, lambda: interrupted["flag"])
        plant = PhysicsPlant(
            scenario.make_plant(config.seed),
            physics_dt=config.physics_dt,
            actuation_delay=config.actuation_delay,
            stop_reason=remote.stop_reason,
        )
        last = {"t": -math.inf}

        def on_step(t: float, progress: float) -> None:
            if t - last["t"] >= _STATUS_PERIOD_S - 1e-9:
                last["t"] = t
                report = {"time": t, "progress": progress, "laps_completed": math.floor(progress)}
                status.publish(String(data=json.dumps({**report, "outcome": None})))

        node.get_logger().info(
            f"{scenario.track.name}: {config.laps} lap(s), {config.clock} clock, "
            f"odometry on {config.odometry_topic}, commands on {config.drive_topic}"
        )
        sim = SimConfig(
            dt=config.period if config.clock == "lockstep" else config.physics_dt,
            laps=config.laps,
            flying_start=not config.standstill,
        )
        result = simulate(plant, remote, scenario.track, scenario.reference, sim, on_step=on_step)
        summary = summary_of(result, config, remote)
        status.publish(String(data=json.dumps(to_json_ready(summary))))
        node.get_logger().info("summary: " + json.dumps(to_json_ready(summary)))
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
            result.log.to_csv(out / "log.csv")
            write_json_atomic(out / "summary.json", summary)
        # Let the final status reach its subscribers before the node goes.
        executor.spin_once(timeout_sec=0.2)
        return 0 if summary["outcome"] == "completed" else 1
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def summary_of(result: SimResult, config: SimNodeConfig, remote: RemoteController) -> dict[str, Any]:
    """The run's outcome, lap times and metrics, and what crossed ROS (JSON-ready)."""
    outcome = result.outcome
    if outcome == "plant_failure" and result.failure is not None and remote.abort is not None:
        outcome = "interrupted" if remote.abort == "interrupted" else "no_controller"
    metrics = lap_metrics(result, config.laps).to_json()
    round_trip = 1e3 * result.log["solve_time_s"]
    round_trip = round_trip[np.isfinite(round_trip)]
    return {
        "outcome": outcome,
        "failure": result.failure if outcome == "plant_failure" else remote.abort,
        "progress": result.progress,
        "lap_times": result.lap_times,
        "metrics": metrics,
        "clock": config.clock,
        "actuation_delay": config.actuation_delay,
        "car": config.car.plant.car,
        "commands_received": remote.received,
        "commands_ignored": remote.ignored,
        "odometry_published": remote.published,
        # Lock-step only: from publishing an odometry to its answer (ms).
        "round_trip_ms_median": float(np.median(round_trip)) if round_trip.size else None,
        "round_trip_ms_p99": float(np.percentile(round_trip, 99)) if round_trip.size else None,
    }
