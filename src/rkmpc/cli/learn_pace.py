"""``rkmpc learn-pace``: learning to race, one pace step per iteration."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rkmpc.cli.common import (
    CACHE_HELP,
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
    parser = sub.add_parser(
        "learn-pace",
        help="learning to race: LMPC laps at a safe pace, then train RKMPC on every clean lap so far "
        "and drive a pace step faster, while the laps stay clean",
    )
    parser.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    parser.add_argument("--controller", default="rkmpc", choices=["rkmpc", "rkmpc-paper", "lmpc-id"])
    parser.add_argument("--scale", type=float, default=None)
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
        controller=args.controller,
        paces=ladder_from_args(args, car),
        seed=car.training.seed,
        scale=args.scale,
        vehicle=car.preset,
        laps=car.training.data_laps,
        epochs=car.training.epochs,
        max_iterations=args.max_iterations,
        cache_dir=None if args.cache_dir is None else str(args.cache_dir),
        car_config=car,
    )


def cmd_learn_pace(args: argparse.Namespace) -> int:
    from rich.console import Console

    from rkmpc.analysis.plots import save_figure
    from rkmpc.analysis.study_plots import plot_learn_pace
    from rkmpc.core.io import check_output_folder, output_folder, write_json_atomic, write_text_atomic
    from rkmpc.experiments.parallel import limit_threads
    from rkmpc.experiments.studies.learn_pace import learn_pace
    from rkmpc.experiments.studies.pace_rules import pace_label

    markers = ("learn_pace.json",)
    check_output_folder(args.out, force=args.force, markers=markers)
    limit_threads()
    config = learn_pace_config(args)
    result = learn_pace(config, say=Console(stderr=True).print)
    text = result.to_markdown()
    with output_folder(args.out, force=args.force, markers=markers) as out:
        write_json_atomic(out / "learn_pace.json", result.to_json())
        write_text_atomic(out / "learn_pace.md", text)
    print(text)
    its = result.iterations
    figure = plot_learn_pace(
        [pace_label(it.pace) for it in its],
        [it.metrics.lap_time_s for it in its],
        [it.clean for it in its],
        [it.lmpc_metrics.lap_time_s if it.lmpc_clean else None for it in its],
        [it.metrics.lateral_error_mean_m for it in its],
        f"learning to race: {args.controller} on {result.to_json()['track']}, seed {config.seed}",
    )
    save_figure(figure, args.out / "learn_pace.png")
    return 0
