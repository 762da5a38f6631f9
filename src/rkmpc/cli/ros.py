"""``rkmpc node`` and ``rkmpc sim-node``, the ROS 2 commands (they need the ``ros`` extra: ``make ros``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rkmpc.cli.common import VEHICLES
from rkmpc.core.errors import RkmpcError

__all__ = ["ROS_COMMANDS", "add_ros_parsers"]

_ROS_ARGS_HELP = "everything after it goes to ROS (e.g. -p safety.odometry_timeout:=1.0, -r /drive:=/cmd)"


def add_ros_parsers(sub: Any) -> None:
    """Add ``node`` and ``sim-node`` to the subcommands ``sub``."""
    node = sub.add_parser("node", help="drive a car over ROS 2 with any controller")
    node.add_argument("--config", required=True, type=Path, help="the car's YAML file (docs/car.md)")
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
    sim.add_argument("--vehicle", default="f1tenth", choices=VEHICLES)
    sim.add_argument(
        "--car", default=None, help="drive a car of the zoo (gym, overshoot, ..., random-<seed>)"
    )
    sim.add_argument(
        "--clock", default="realtime", choices=["realtime", "lockstep"], help="wall clock, or lock-step"
    )
    sim.add_argument("--laps", type=int, default=1, help="laps before the node reports and exits")
    sim.add_argument("--period", type=float, default=0.05, help="control period in lock-step (s)")
    sim.add_argument("--physics-rate", type=float, default=100.0, help="physics steps per second")
    sim.add_argument(
        "--odometry-rate", type=float, default=50.0, help="odometry messages per second (real time)"
    )
    sim.add_argument("--actuation-delay", type=float, default=0.0, help="added delay of every command (s)")
    sim.add_argument(
        "--standstill", action="store_true", help="start at rest instead of at the reference speed"
    )
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--odometry-topic", default="/ego_racecar/odom")
    sim.add_argument("--drive-topic", default="/drive")
    sim.add_argument("--steering-topic", default="", help="publish the true wheel angle here (Float64, rad)")
    sim.add_argument("--status-topic", default="/rkmpc/sim/status")
    sim.add_argument("--answer-timeout", type=float, default=30.0, help="lock-step: give up after (s)")
    sim.add_argument(
        "--startup-timeout", type=float, default=None, help="wait for the first command at most (s)"
    )
    sim.add_argument("--out", type=Path, default=None, help="folder for summary.json and log.csv")
    sim.add_argument(
        "--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=None, help=_ROS_ARGS_HELP
    )


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
    return run_node(
        args.config,
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
        track=args.track,
        raceline=args.raceline,
        scale=args.scale,
        vehicle=args.vehicle,
        car=args.car,
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


#: The ROS subcommands by name.
ROS_COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {"node": cmd_node, "sim-node": cmd_sim_node}
