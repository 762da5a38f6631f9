"""``rkmpc node``, ``sim-node`` and ``car-loop``, the ROS 2 commands (the ``ros`` extra: ``make ros``)."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rkmpc.cli.common import add_config_args, at_least, car_config
from rkmpc.core.errors import RkmpcError

__all__ = ["ROS_COMMANDS", "add_car_loop_parser", "add_ros_parsers"]

_ROS_ARGS_HELP = "everything after it goes to ROS (e.g. -p safety.odometry_timeout:=1.0, -r /drive:=/cmd)"


def add_ros_parsers(sub: Any) -> None:
    """Add ``node`` and ``sim-node`` to the subcommands ``sub``."""
    node = sub.add_parser("node", help="drive a car over ROS 2 with any controller")
    node.add_argument(
        "--config",
        required=True,
        type=Path,
        metavar="CAR.toml",
        help="the car file every command reads (TOML, or YAML), with its [ros] section (docs/car.md)",
    )
    node.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    node.add_argument(
        "--raceline", default=None, help="TUM race-line CSV to track instead of the centre line"
    )
    node.add_argument("--scale", type=float, default=None, help="scale of track files (default: the car's)")
    node.add_argument("--controller", default="lmpc", help="controller to drive with (default: lmpc)")
    node.add_argument("--model", default=None, help="model file of a learned controller")
    node.add_argument(
        "--allow-mismatch", action="store_true", help="drive a model made for another car or period (warned)"
    )
    node.add_argument(
        "--out", type=Path, default=None, help="folder for what the node decided, written at exit"
    )
    node.add_argument(
        "--record",
        type=Path,
        default=None,
        metavar="BAG",
        help="record the odometry, wheel angles and commands to this new ROS 2 bag folder (record.bag)",
    )
    node.add_argument(
        "--record-storage", default=None, choices=["mcap", "sqlite3"], help="the bag's storage (mcap)"
    )
    node.add_argument(
        "--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=None, help=_ROS_ARGS_HELP
    )

    sim = sub.add_parser("sim-node", help="the simulated car as a ROS 2 node (odometry out, /drive in)")
    sim.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    sim.add_argument("--raceline", default=None, help="TUM race-line CSV to track instead of the centre line")
    sim.add_argument(
        "--scale", type=float, default=None, help="scale of track files (default: 0.1 for f1tenth)"
    )
    add_config_args(sim, pace=False)
    sim.add_argument(
        "--car", default=None, help="drive a car of the zoo (gym, overshoot, ..., random-<seed>)"
    )
    sim.add_argument(
        "--clock", default="realtime", choices=["realtime", "lockstep"], help="wall clock, or lock-step"
    )
    sim.add_argument("--laps", type=at_least(1), default=1, help="laps before the node reports and exits")
    sim.add_argument("--period", type=float, default=0.05, help="control period in lock-step (s)")
    sim.add_argument("--physics-rate", type=float, default=100.0, help="physics steps per second")
    sim.add_argument(
        "--odometry-rate", type=float, default=50.0, help="odometry messages per second (real time)"
    )
    sim.add_argument("--actuation-delay", type=float, default=0.0, help="added delay of every command (s)")
    sim.add_argument(
        "--standstill", action="store_true", help="start at rest instead of at the reference speed"
    )
    sim.add_argument("--seed", type=at_least(0), default=0, help="seed of the simulated car's noise")
    sim.add_argument("--odometry-topic", default="/ego_racecar/odom", help="the odometry it publishes")
    sim.add_argument("--drive-topic", default="/drive", help="the commands it takes")
    sim.add_argument("--steering-topic", default="", help="publish the true wheel angle here (Float64, rad)")
    sim.add_argument("--status-topic", default="/rkmpc/sim/status", help="where it says how the run goes")
    sim.add_argument("--answer-timeout", type=float, default=30.0, help="lock-step: give up after (s)")
    sim.add_argument(
        "--startup-timeout", type=float, default=None, help="wait for the first command at most (s)"
    )
    sim.add_argument("--out", type=Path, default=None, help="folder for summary.json and log.csv")
    sim.add_argument(
        "--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=None, help=_ROS_ARGS_HELP
    )
    add_car_loop_parser(sub)


def add_car_loop_parser(sub: Any) -> None:
    """Add ``car-loop``: the paper's on-car workflow on loopback (:mod:`rkmpc.ros.workflow`)."""
    loop = sub.add_parser(
        "car-loop",
        help="record LMPC laps over ROS 2, train from the bag, drive LMPC, lmpc-id, RKMPC: Table II",
    )
    loop.add_argument("--out", required=True, type=Path, help="output folder (see docs/car.md)")
    loop.add_argument(
        "--clock",
        default="lockstep",
        choices=["lockstep", "realtime"],
        help="lock-step (results independent of the machine's load) or the wall clock",
    )
    loop.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    loop.add_argument(
        "--delay-study",
        type=float,
        default=0.05,
        metavar="SECONDS",
        help="added actuation delay of the latency-compensation runs (LMPC, RKMPC); 0 skips them",
    )
    loop.add_argument(
        "--seed", type=at_least(0), default=0, help="seed of the simulated car and the training"
    )
    loop.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: from the pid)")
    loop.add_argument(
        "--timeout", type=float, default=3600.0, help="bound of each process (s), against hangs"
    )
    loop.add_argument(
        "--sensors",
        default="f1tenth-real",
        metavar="PROFILE",
        help="the simulated car's sensors: f1tenth-real (no wheel angle: no steering topic, the node "
        "estimates) or ideal (its wheel angle on a steering topic)",
    )
    loop.add_argument("--force", action="store_true", help="replace an earlier car-loop output folder")


def _ros_args(args: argparse.Namespace) -> list[str]:
    return ["rkmpc"] + ([] if args.ros_args is None else ["--ros-args", *args.ros_args])


def _missing_ros(exc: ImportError) -> RkmpcError:
    return RkmpcError(
        f"ROS 2 is not installed ({exc}); install it with `make ros` "
        "(pip install 'rkmpc[ros]', then ros/build_msgs.sh VENV for ackermann_msgs)"
    )


def cmd_node(args: argparse.Namespace) -> int:
    try:
        from rkmpc.ros.node import run_node
    except ImportError as exc:
        raise _missing_ros(exc) from None
    from rkmpc.ros.config import NodeTask

    task = NodeTask(
        track=args.track,
        raceline=args.raceline,
        scale=args.scale,
        controller=args.controller,
        model=args.model,
        allow_mismatch=args.allow_mismatch,
    )
    return run_node(
        args.config,
        task,
        out=args.out,
        record=args.record,
        record_storage=args.record_storage,
        ros_args=_ros_args(args),
    )


def cmd_sim_node(args: argparse.Namespace) -> int:
    try:
        from rkmpc.ros.sim_node import run_sim_node
    except ImportError as exc:
        raise _missing_ros(exc) from None
    from rkmpc.ros.sim_config import SimNodeConfig

    config = SimNodeConfig(
        car=car_config(args),
        track=args.track,
        raceline=args.raceline,
        scale=args.scale,
        clock=args.clock,
        laps=args.laps,
        period=args.period,
        physics_rate_hz=args.physics_rate,
        odometry_rate_hz=args.odometry_rate,
        actuation_delay=args.actuation_delay,
        standstill=args.standstill,
        seed=args.seed,
        odometry_topic=args.odometry_topic,
        drive_topic=args.drive_topic,
        steering_topic=args.steering_topic,
        status_topic=args.status_topic,
        answer_timeout=args.answer_timeout,
        startup_timeout=args.startup_timeout,
    )
    return run_sim_node(config, out=args.out, ros_args=_ros_args(args))


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def cmd_car_loop(args: argparse.Namespace) -> int:
    import importlib.util

    from rkmpc.ros.workflow import WorkflowConfig, run_workflow
    from rkmpc.ros.workflow_report import markdown_report

    for module, install in (
        ("rclpy", "make ros"),
        ("ackermann_msgs", "make ros"),
        ("rosbags", "make ros"),
        ("torch", "the train extra: make"),
    ):
        if importlib.util.find_spec(module) is None:
            raise RkmpcError(f"rkmpc car-loop needs {module}: install it with {install}")
    config = WorkflowConfig(
        out=str(args.out),
        clock=args.clock,
        track=args.track,
        delay=args.delay_study,
        seed=args.seed,
        domain_id=args.domain_id,
        force=args.force,
        timeout=args.timeout,
        sensors=args.sensors,
    )
    # Ctrl-C stops the processes, and SIGTERM as Ctrl-C does; set here, like every other command's
    # handler, so that a car-loop started with SIGINT ignored (a background job) still stops.
    previous = {sig: signal.signal(sig, _interrupt) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        report = run_workflow(config, say=lambda message: print(message, flush=True))
    except KeyboardInterrupt:
        print("rkmpc: interrupted; every process of the run was stopped", file=sys.stderr)
        return 130
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print(markdown_report(report))
    print(f"-> {args.out / 'table2.md'}, {args.out / 'table2.json'}")
    return 0


#: The ROS subcommands by name.
ROS_COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "node": cmd_node,
    "sim-node": cmd_sim_node,
    "car-loop": cmd_car_loop,
}
