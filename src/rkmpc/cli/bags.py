"""``rkmpc collect --from-bag PATH``: a bag recorded on a car (ROS 1, ROS 2 sqlite3 or MCAP) as a data set."""

from __future__ import annotations

import argparse
import sys

__all__ = ["add_bag_args", "cmd_collect_from_bag"]


def add_bag_args(parser: argparse.ArgumentParser) -> None:
    """The ``--from-bag`` option of ``rkmpc collect`` and the options of the import."""
    from rkmpc.learning.data.bags.config import DEFAULT_DRIVE_TOPIC, DEFAULT_ODOM_TOPIC, ODOM_FRAMES

    group = parser.add_argument_group("importing a bag (--from-bag; see docs/car.md)")
    group.add_argument(
        "--from-bag",
        default=None,
        metavar="PATH",
        help="instead: read a ROS 1 .bag or a ROS 2 bag folder (sqlite3, MCAP) recorded on a car",
    )
    group.add_argument(
        "--odom-topic", default=DEFAULT_ODOM_TOPIC, help="nav_msgs/Odometry topic (ForzaETH: /car_state/odom)"
    )
    group.add_argument(
        "--drive-topic", default=DEFAULT_DRIVE_TOPIC, help="ackermann_msgs/AckermannDriveStamped topic"
    )
    group.add_argument(
        "--steer-topic", default=None, help="std_msgs/Float64 topic of the measured wheel angle (optional)"
    )
    group.add_argument(
        "--steer-gain",
        type=float,
        default=1.0,
        help="the steer topic carries GAIN * angle + OFFSET (VESC: steering_angle_to_servo_gain)",
    )
    group.add_argument(
        "--steer-offset",
        type=float,
        default=0.0,
        help="see --steer-gain (VESC: steering_angle_to_servo_offset)",
    )
    group.add_argument(
        "--odom-frame",
        default="cog",
        choices=ODOM_FRAMES,
        help="where the odometry's child frame sits: centre of gravity (F1TENTH simulator) or rear axle",
    )
    group.add_argument("--dt", type=float, default=0.05, help="control period to resample onto (s)")
    group.add_argument(
        "--max-gap", type=float, default=None, help="odometry gap (s) that starts a new episode (3 periods)"
    )
    group.add_argument(
        "--command-tolerance",
        type=float,
        default=None,
        help="a command stamped up to this long (s) after a sample counts for it (a quarter period)",
    )
    group.add_argument(
        "--receive-time",
        action="store_true",
        help="time messages by the bag's receive time, not their stamps",
    )
    group.add_argument("--min-samples", type=int, default=20, help="fewer transitions than this are an error")


def cmd_collect_from_bag(args: argparse.Namespace) -> int:
    """Import the bag of ``--from-bag`` and save the data set to ``--out``."""
    from rkmpc.cli.common import car_config
    from rkmpc.learning.data.bags import BagImportConfig, import_bag

    config = BagImportConfig(
        dt=args.dt,
        odom_topic=args.odom_topic,
        drive_topic=args.drive_topic,
        steer_topic=args.steer_topic,
        steer_gain=args.steer_gain,
        steer_offset=args.steer_offset,
        odom_frame=args.odom_frame,
        stamps="receive" if args.receive_time else "header",
        max_gap=args.max_gap,
        command_tolerance=args.command_tolerance,
        min_samples=args.min_samples,
    )
    if args.from_log is not None or args.excitation:
        raise ValueError("--from-bag, --from-log and --excitation exclude each other")
    try:
        data = import_bag(args.from_bag, car_config(args).vehicle, config, scale=args.scale)
    except ImportError as exc:  # pragma: no cover - depends on the environment
        print(f"rkmpc: error: {exc}", file=sys.stderr)
        return 2
    data.save(args.out)
    episodes = len(set(data.episode.tolist()))
    print(f"{len(data)} transitions in {episodes} episode(s) from {args.from_bag} -> {args.out}")
    return 0
