"""``rkmpc learn-pace``: learning to race, one pace step per iteration."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rkmpc.cli.common import (
    CACHE_HELP,
    SCALE_HELP,
    add_config_args,
    add_force_arg,
    add_ladder_args,
    at_least,
    car_config,
    ladder_from_args,
)

if TYPE_CHECKING:
    from rkmpc.experiments.studies.learn_pace import LearnPaceConfig

__all__ = ["add_learn_pace_parser", "cmd_learn_pace", "learn_pace_config"]


def add_learn_pace_parser(sub: Any) -> None:
    from rkmpc.learning.recipes import track_learners

    parser = sub.add_parser(
        "learn-pace",
        help="learning to race: LMPC laps at a safe pace, then train RKMPC on every clean lap so far "
        "and drive a pace step faster, while the laps stay clean",
    )
    parser.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    parser.add_argument(
        "--controller",
        default="rkmpc",
        choices=track_learners(),
        help="the learned controller that climbs the ladder",
    )
    parser.add_argument("--scale", type=float, default=None, help=SCALE_HELP)
    add_config_args(parser, pace=False)  # the pace is the ladder's, from the car's own
    add_ladder_args(parser)
    parser.add_argument(
        "--seed", type=at_least(0), default=None, help="else the --config file's (default: 0)"
    )
    parser.add_argument(
        "--laps",
        dest="data_laps",
        type=at_least(1),
        default=None,
        metavar="N",
        help="laps recorded at every iteration; else the --config file's data_laps (default: 2)",
    )
    parser.add_argument(
        "--epochs",
        type=at_least(1),
        default=None,
        help="training epochs; else the --config file's (default: the recipe's, 100)",
    )
    parser.add_argument(
        "--max-iterations",
        type=at_least(1),
        default=None,
        help="iterations after the LMPC's (default: the ladder)",
    )
    parser.add_argument("--cache-dir", type=Path, default=None, help=CACHE_HELP)
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    add_force_arg(parser)


def learn_pace_config(args: argparse.Namespace) -> LearnPaceConfig:
    """The settings of ``learn-pace``: the options, then the car file, then the preset."""
    from rkmpc.experiments.studies.learn_pace import LearnPaceConfig

    car = car_config(args)
    return LearnPaceConfig(
        track=args.track,
        car=car,
        controller=args.controller,
        paces=ladder_from_args(args, car),
        scale=args.scale,
        max_iterations=args.max_iterations,
        cache_dir=None if args.cache_dir is None else str(args.cache_dir),
    )


def cmd_learn_pace(args: argparse.Namespace) -> int:
    from rkmpc.cli.study import run_study_command
    from rkmpc.experiments.studies.learn_pace import LearnPaceStudy

    args.jobs, args.backend, args.address = 1, "loky", None
    return run_study_command(args, LearnPaceStudy(learn_pace_config(args)), "learn_pace")
