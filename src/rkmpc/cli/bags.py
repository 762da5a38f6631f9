"""``rkmpc collect --from-bag PATH`` or ``--from-csv DIR``: what a car recorded, as a data set."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rkmpc.learning.data.window import TimeWindow

__all__ = ["add_bag_args", "cmd_collect_from_bag", "cmd_collect_from_csv", "quality_path"]


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
    group.add_argument(
        "--no-lateral-velocity",
        action="store_true",
        help="the odometry's twist.linear.y is not measured (a particle filter's): side slip NaN "
        "(the default when the car's sensors measure no side slip, e.g. --sensors f1tenth-real)",
    )
    group.add_argument(
        "--no-yaw-rate",
        action="store_true",
        help="the odometry's twist.angular.z is not measured: yaw rate NaN",
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
    group.add_argument(
        "--pose-latency",
        type=float,
        default=0.0,
        metavar="S",
        help="the odometry's pose is this much older than its stamp (s): the labels' smoother dates it "
        "back (the rkmpc simulated car's odometry: its localiser latency, 0.03 for f1tenth-real)",
    )
    group.add_argument(
        "--window",
        default=None,
        metavar="START:END",
        help="--from-bag, --from-csv: keep this stretch, s from the start (10:60, :45) or @stamps (@T0:@T1)",
    )
    csv = parser.add_argument_group("importing a CSV log (--from-csv)")
    csv.add_argument("--from-csv", default=None, metavar="DIR", help="instead: read a folder of CSV files")
    csv.add_argument(
        "--csv-spec",
        default=None,
        metavar="NAME|SPEC.toml",
        help="the log's column mapping and import settings: a preset (friction-maps) or a TOML file",
    )


def cmd_collect_from_bag(args: argparse.Namespace) -> int:
    """Import the bag of ``--from-bag`` and save the data set to ``--out``."""
    from rkmpc.cli.common import car_config
    from rkmpc.learning.data.bags import BagImportConfig, import_bag
    from rkmpc.learning.data.bags.stream import SEGMENT_S

    car = car_config(args)
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
        lateral_velocity=car.sensors.measures_slip_angle and not args.no_lateral_velocity,
        yaw_rate=not args.no_yaw_rate,
        window=_window(args),
        pose_latency=args.pose_latency,
    )
    if args.from_log is not None or args.excitation:
        raise ValueError("--from-bag, --from-log and --excitation exclude each other")
    try:
        data = import_bag(args.from_bag, car.vehicle, config, scale=args.scale)
    except ImportError as exc:  # pragma: no cover - depends on the environment
        print(f"rkmpc: error: {exc}", file=sys.stderr)
        return 2
    data.save(args.out)
    if data.metadata["recording"] == "unfinished":
        print(
            f"warning: {args.from_bag} is a recording that never ended (its recorder was killed?): "
            f"read up to its last closed segment, the last {SEGMENT_S:g} s at most are missing",
            file=sys.stderr,
        )
    episodes = len(set(data.episode.tolist()))
    print(f"{len(data)} transitions in {episodes} episode(s) from {args.from_bag} -> {args.out}")
    return 0


def _window(args: argparse.Namespace) -> TimeWindow | None:
    from rkmpc.learning.data.window import TimeWindow

    return None if args.window is None else TimeWindow.parse(args.window)


def quality_path(out: Path) -> Path:
    """Where the quality report of the data set ``out`` goes: ``D.npz`` -> ``D.quality.json``."""
    return out.with_name(f"{out.stem if out.suffix == '.npz' else out.name}.quality.json")


def cmd_collect_from_csv(args: argparse.Namespace) -> int:
    """Import the CSV log of ``--from-csv``, print its quality report, save the data set and the report."""
    from rkmpc.cli.common import car_config
    from rkmpc.core.io import write_json_atomic
    from rkmpc.learning.data.logs import csv_spec, import_csv_log

    if args.from_bag is not None or args.from_log is not None or args.excitation:
        raise ValueError("--from-csv, --from-bag, --from-log and --excitation exclude each other")
    if args.csv_spec is None:
        raise ValueError("--from-csv needs --csv-spec: a preset (friction-maps) or a TOML spec file")
    spec = csv_spec(args.csv_spec)
    result = import_csv_log(
        args.from_csv, car_config(args).vehicle, spec, window=_window(args), scale=args.scale
    )
    out = Path(args.out)
    result.data.save(out)
    report = quality_path(out)
    write_json_atomic(report, result.report.to_json())
    print(result.report.to_markdown())
    episodes = len(set(result.data.episode.tolist()))
    print(f"{len(result.data)} transitions in {episodes} episode(s) from {args.from_csv} -> {out} ({report})")
    return 0
