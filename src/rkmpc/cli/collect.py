"""``rkmpc collect``: record on-track or random-excitation data, or import a log, a bag or CSV files."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

from rkmpc.cli.bags import add_bag_args, cmd_collect_from_bag, cmd_collect_from_csv
from rkmpc.cli.common import add_scenario_args, car_config

__all__ = ["add_collect_parser", "cmd_collect"]


def add_collect_parser(sub: Any) -> None:
    collect = sub.add_parser("collect", help="record on-track (or random-excitation) data, or import a log")
    collect.add_argument(
        "--controller", default="lmpc", choices=["pp", "lmpc"], help="the controller that drives the laps"
    )
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
    add_scenario_args(collect, out_help="output data set file (.npz)", laps_help="laps of data to record")
    add_bag_args(collect)
    collect.set_defaults(laps=2)


def cmd_collect(args: argparse.Namespace) -> int:
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
