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
from collections.abc import Callable, Iterator, Sequence
from importlib.metadata import version as package_version
from typing import Any

from rkmpc.cli.collect import add_collect_parser, cmd_collect
from rkmpc.cli.common import add_learning_args, add_scenario_args
from rkmpc.cli.compare import cmd_compare
from rkmpc.cli.evaluate import add_evaluate_parser, cmd_evaluate
from rkmpc.cli.learn_pace import add_learn_pace_parser, cmd_learn_pace
from rkmpc.cli.ros import ROS_COMMANDS, add_ros_parsers
from rkmpc.cli.study import add_study_parser, cmd_study
from rkmpc.cli.train import add_train_parser, cmd_train
from rkmpc.core.errors import ContractError, IdentificationWarning, RkmpcError
from rkmpc.core.interrupt import interruptible

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

    parser = _Parser(prog="rkmpc", description=_DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"rkmpc {package_version('rkmpc')}")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="drive one controller around a track")
    run.add_argument(
        "--controller", required=True, choices=sorted(CONTROLLERS), help="the controller to drive"
    )
    add_scenario_args(run)
    add_learning_args(run)
    compare = sub.add_parser(
        "compare",
        help="learn on the track, drive several controllers and tabulate them (the paper's Table I)",
    )
    compare.add_argument(
        "--controllers", default=",".join(ALL_CONTROLLERS), help="comma-separated controller names"
    )
    add_scenario_args(compare)
    add_learning_args(compare)
    compare.add_argument(
        "--also-sensors",
        default="f1tenth-real",
        metavar="PROFILE",
        help="drive the comparison again with these sensors (learning from data recorded with them), "
        "into OUT/sensors-PROFILE/; none: skip",
    )
    add_collect_parser(sub)
    add_train_parser(sub)
    add_evaluate_parser(sub)
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
        "collect": cmd_collect,
        "train": cmd_train,
        "evaluate": cmd_evaluate,
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
        with warnings.catch_warnings(), catch, _one_line_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            return commands[args.command](args)
    except ContractError as exc:  # the flag, not the library's argument, is the way out here
        print(f"rkmpc: error: {exc.for_command_line()}", file=sys.stderr)
        return 2
    except (RkmpcError, ValueError, OSError, ImportError) as exc:
        # An ImportError is an optional package not installed (a backend, torch, rosbags): its
        # message says which and how to install it.
        print(f"rkmpc: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # Every output is written whole or not at all, and a run's folder only appears when it is
        # complete (rkmpc.core.io): nothing to clean up, nothing to say but this.
        print("rkmpc: interrupted", file=sys.stderr)
        return 130


@contextlib.contextmanager
def _one_line_warnings() -> Iterator[None]:
    """Warnings shown as ``rkmpc: warning: MESSAGE``, one line without the source (as errors are)."""
    before = warnings.formatwarning

    def one_line(message: Warning | str, category: type[Warning], *_: Any, **__: Any) -> str:
        return f"rkmpc: warning: {message}\n"

    warnings.formatwarning = one_line
    try:
        yield
    finally:
        warnings.formatwarning = before


def _cmd_tracks(_: argparse.Namespace) -> int:
    from rkmpc.track.builtin import BUILTIN_DESCRIPTIONS, builtin_track

    for name, text in BUILTIN_DESCRIPTIONS.items():
        length = builtin_track(name).centerline.length
        print(f"{name:12s} {length:7.1f} m  {text}")
    return 0
