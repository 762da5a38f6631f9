"""Command line: ``rkmpc run | compare | collect | train | tracks | study ... | learn-pace | node | ...``.

This module only parses arguments and dispatches to the library; what each
command computes and writes lives in :mod:`rkmpc.experiments`, :mod:`rkmpc.sim`
and :mod:`rkmpc.learning`.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import replace
from importlib.metadata import version as package_version
from pathlib import Path
from typing import Any

from rkmpc.cli.bags import add_bag_args, cmd_collect_from_bag, cmd_collect_from_csv
from rkmpc.cli.common import CACHE_HELP, add_config_args, add_force_arg, at_least, car_config
from rkmpc.cli.compare import cmd_compare
from rkmpc.cli.learn_pace import add_learn_pace_parser, cmd_learn_pace
from rkmpc.cli.ros import ROS_COMMANDS, add_ros_parsers
from rkmpc.cli.study import add_study_parser, cmd_study
from rkmpc.core.errors import IdentificationWarning, RkmpcError
from rkmpc.core.interrupt import interruptible


def _add_scenario_args(parser: argparse.ArgumentParser, out_help: str = "output folder") -> None:
    parser.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    parser.add_argument(
        "--raceline", default=None, help="TUM race-line CSV to track instead of the centre line"
    )
    parser.add_argument(
        "--scale", type=float, default=None, help="scale of track files (default: 0.1 for f1tenth)"
    )
    add_config_args(parser)
    parser.add_argument(
        "--car", default=None, help="drive a car of the zoo (gym, overshoot, ..., random-<seed>) instead"
    )
    parser.add_argument("--laps", type=at_least(1), default=1)
    parser.add_argument(
        "--seed",
        type=at_least(0),
        default=None,
        help="seed of every random choice; else the --config file's (default: 0)",
    )
    parser.add_argument("--noise", action="store_true", help="add measurement noise to the observations")
    parser.add_argument("--out", required=True, type=Path, help=out_help)
    parser.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="[NAME=]PATH",
        help="model file of a learned controller (rkmpc, rkmpc-paper, kmpc, lmpc-id); repeat as NAME=PATH",
    )


def _add_learning_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--data-laps",
        type=at_least(1),
        default=None,
        help="LMPC laps of data the learned controllers learn from; else the --config file's (default: 2)",
    )
    parser.add_argument(
        "--kmpc-samples",
        type=at_least(1000),
        default=None,
        help="random-excitation samples of the KMPC model; else the --config file's (default: 50000)",
    )
    parser.add_argument(
        "--fault",
        default=None,
        help="also drive every controller with this fault (noise, delay, friction, heavy); report the effect",
    )
    parser.add_argument("--cache-dir", type=Path, default=None, help=CACHE_HELP)
    parser.add_argument("--no-cache", action="store_true", help="train every model afresh, store nothing")
    parser.add_argument(
        "--epochs",
        type=at_least(1),
        default=None,
        help="training epochs of the learned models; else the --config file's, else the recipes'",
    )
    _add_mismatch_arg(parser, "drive with --model files made with another car, period or track scale")
    add_force_arg(parser)


def _add_mismatch_arg(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument(
        "--allow-mismatch", action="store_true", help=f"{what} (refused otherwise; the results record it)"
    )


_DESCRIPTION = (
    "Residual Koopman MPC for cars on race tracks: drive a controller (run), learn on a track and "
    "compare controllers (compare, the paper's Table I), record and train (collect, train), studies "
    "over tracks, cars and data volume (study), and on a car over ROS 2 (node, sim-node, car-loop). "
    "'rkmpc COMMAND -h' lists a command's options with their defaults."
)


class _DefaultsFormatter(argparse.HelpFormatter):
    """Adds ``(default: X)`` to an option's help where there is a default to tell and the help does not."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (
            not action.option_strings
            or default is None
            or default is False
            or default == argparse.SUPPRESS
            or default == []
            or "default" in text
            or "%(default)" in text
        ):
            return action.help
        return f"{text} (default: %(default)s)".strip()


class _Parser(argparse.ArgumentParser):
    """Every (sub)command's help shows the options' defaults."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _DefaultsFormatter)
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``rkmpc`` command."""
    from rkmpc.control.registry import CONTROLLERS
    from rkmpc.experiments.compare import ALL_CONTROLLERS
    from rkmpc.learning.recipes import model_kinds

    parser = _Parser(prog="rkmpc", description=_DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"rkmpc {package_version('rkmpc')}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="drive one controller around a track")
    run.add_argument("--controller", required=True, choices=sorted(CONTROLLERS))
    _add_scenario_args(run)
    _add_learning_args(run)
    compare = sub.add_parser(
        "compare",
        help="learn on the track, drive several controllers and tabulate them (the paper's Table I)",
    )
    compare.add_argument(
        "--controllers", default=",".join(ALL_CONTROLLERS), help="comma-separated controller names"
    )
    _add_scenario_args(compare)
    _add_learning_args(compare)
    collect = sub.add_parser("collect", help="record on-track (or random-excitation) data")
    collect.add_argument("--controller", default="lmpc", choices=["pp", "lmpc"])
    collect.add_argument(
        "--excitation",
        type=int,
        default=0,
        metavar="N",
        help="instead: N random-excitation samples (for KMPC)",
    )
    collect.add_argument(
        "--from-log",
        type=Path,
        default=None,
        metavar="LOG",
        help="instead: turn an earlier run's log.csv into data",
    )
    _add_scenario_args(collect, out_help="output data set file (.npz)")
    add_bag_args(collect)
    collect.set_defaults(laps=2)
    train = sub.add_parser("train", help="train a model from a data set")
    train.add_argument("--data", required=True, type=Path)
    train.add_argument("--kind", required=True, choices=model_kinds())
    add_config_args(train, pace=False)  # the car the model is for
    train.add_argument("--dt", type=float, default=0.05, help="control period the model is for (s)")
    _add_mismatch_arg(train, "train on data recorded with another car or period")
    train.add_argument(
        "--epochs", type=at_least(1), default=None, help="else the --config file's, else the recipe's"
    )
    train.add_argument("--seed", type=at_least(0), default=None, help="else the --config file's (default: 0)")
    train.add_argument("--out", required=True, type=Path, help="model file")
    sub.add_parser("tracks", help="list the built-in tracks")
    add_study_parser(sub)
    add_learn_pace_parser(sub)
    add_ros_parsers(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    args = build_parser().parse_args(argv)
    commands: dict[str, Callable[[argparse.Namespace], int]] = {
        "tracks": _cmd_tracks,
        "collect": _cmd_collect,
        "train": _cmd_train,
        "study": cmd_study,
        "learn-pace": cmd_learn_pace,
        "run": cmd_compare,
        "compare": cmd_compare,
        **ROS_COMMANDS,
    }
    try:
        # Identification warnings are part of each command's own report (train's lines, the
        # comparison's messages and results.json), not Python warnings on stderr besides.
        # The ROS commands handle SIGINT themselves (rclpy, the car-loop's processes).
        catch = contextlib.nullcontext() if args.command in ROS_COMMANDS else interruptible()
        with warnings.catch_warnings(), catch:
            warnings.simplefilter("ignore", IdentificationWarning)
            return commands[args.command](args)
    except (RkmpcError, ValueError, OSError) as exc:
        print(f"rkmpc: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # Every output is written whole or not at all, and a run's folder only appears when it is
        # complete (rkmpc.core.io): nothing to clean up, nothing to say but this.
        print("rkmpc: interrupted", file=sys.stderr)
        return 130


def _cmd_tracks(_: argparse.Namespace) -> int:
    from rkmpc.track.builtin import BUILTIN_DESCRIPTIONS, builtin_track

    for name, text in BUILTIN_DESCRIPTIONS.items():
        length = builtin_track(name).centerline.length
        print(f"{name:12s} {length:7.1f} m  {text}")
    return 0


def _cmd_collect(args: argparse.Namespace) -> int:
    from rkmpc.core.io import check_output_file
    from rkmpc.learning.data.dataset import TransitionDataset
    from rkmpc.sim.collect import collect, collect_excitation
    from rkmpc.sim.faults import DEFAULT_NOISE
    from rkmpc.sim.log import StepLog

    check_output_file(args.out)
    if args.from_bag is not None:
        return cmd_collect_from_bag(args)
    if args.from_csv is not None:
        return cmd_collect_from_csv(args)
    if args.from_log is not None:
        log = StepLog.from_csv(args.from_log)
        data = TransitionDataset.from_log(log, metadata={**log.metadata, "source": str(args.from_log)})
    else:
        from rkmpc.sim.scenario import Scenario

        car = car_config(args)
        scenario = Scenario.from_car(car, args.track, scale=args.scale, raceline=args.raceline)
        seed = car.training.seed
        if args.excitation:
            data = collect_excitation(scenario, n_samples=args.excitation, seed=seed)
        else:
            noise = DEFAULT_NOISE if args.noise else None
            data = collect(scenario, controller=args.controller, laps=args.laps, seed=seed, noise=noise)
        data = replace(data, metadata={**data.metadata, "car_config": car.to_json()})
    data.save(args.out)
    print(f"{len(data)} transitions -> {args.out}")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.progress import Progress

    from rkmpc.core.io import check_output_file
    from rkmpc.core.progress import EpochProgress
    from rkmpc.experiments.training import train_to_file
    from rkmpc.learning.contract import Provenance
    from rkmpc.learning.data.dataset import TransitionDataset

    check_output_file(args.out)
    data = TransitionDataset.load(args.data)
    car = car_config(args)
    vehicle = car.vehicle
    made_for = Provenance(vehicle=car.preset, dt=args.dt, wheelbase=vehicle.wheelbase)
    console = Console(stderr=True)
    epochs = car.training.epochs
    total = epochs or 100
    with Progress(console=console, transient=True, disable=not console.is_terminal) as progress:
        task = progress.add_task(f"training {args.kind}", total=total)
        # A bar (with the time left) on a terminal; about ten lines with an estimate in a log.
        told = EpochProgress(console.print, f"training {args.kind}", total)

        def on_epoch(epoch: int, loss: float) -> None:
            if console.is_terminal:
                progress.update(task, completed=epoch, description=f"training {args.kind} (loss {loss:.3g})")
            else:
                told(epoch, loss)

        lines = train_to_file(
            data,
            made_for,
            vehicle,
            args.kind,
            args.out,
            seed=car.training.seed,
            epochs=epochs,
            on_epoch=on_epoch if args.kind != "identified" else None,
            allow_mismatch=args.allow_mismatch,
            source=str(args.data),
        )
    print("\n".join(lines))
    return 0
