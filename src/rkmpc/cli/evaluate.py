"""``rkmpc evaluate``: how well trained models predict recorded driving, against the kinematic model."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rkmpc.cli.common import add_config_args, add_force_arg, car_config, ints

__all__ = ["add_evaluate_parser", "cmd_evaluate"]


def add_evaluate_parser(sub: Any) -> None:
    parser = sub.add_parser(
        "evaluate",
        help="open-loop k-step prediction of recorded driving by trained models vs the kinematic one",
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--data", type=Path, default=None, help="a data set (.npz: rkmpc collect)")
    source.add_argument(
        "--from-bag", type=Path, default=None, metavar="BAG", help="a ROS bag (its topics as collect's)"
    )
    source.add_argument("--from-csv", type=Path, default=None, metavar="DIR", help="a folder of CSV logs")
    parser.add_argument(
        "--csv-spec", default="friction-maps", help="with --from-csv: a column-mapping preset or TOML file"
    )
    parser.add_argument(
        "--window", default=None, metavar="START:END", help="with --from-bag/--from-csv: seconds of the log"
    )
    parser.add_argument(
        "--model",
        action="append",
        required=True,
        metavar="PATH",
        help="a trained model file (residual, identified, koopman); repeat for more",
    )
    parser.add_argument("--horizons", default="1,5,10,20", help="steps ahead to score, comma-separated")
    add_config_args(parser, pace=False)  # the car: its wheelbase, servo, and the estimator's settings
    parser.add_argument("--out", required=True, type=Path, help="output folder (evaluation.json, .md, .png)")
    add_force_arg(parser)


def _data(args: argparse.Namespace, car: Any) -> tuple[Any, str]:
    from rkmpc.learning.data.dataset import TransitionDataset
    from rkmpc.learning.data.window import TimeWindow

    window = None if args.window is None else TimeWindow.parse(args.window)
    if args.data is not None:
        return TransitionDataset.load(args.data), str(args.data)
    if args.from_bag is not None:
        from rkmpc.learning.data.bags import BagImportConfig, import_bag

        return import_bag(args.from_bag, car.vehicle, BagImportConfig(window=window)), str(args.from_bag)
    from rkmpc.learning.data.logs import csv_spec, import_csv_log

    imported = import_csv_log(args.from_csv, car.vehicle, csv_spec(args.csv_spec), window=window)
    return imported.data, str(args.from_csv)


def cmd_evaluate(args: argparse.Namespace) -> int:
    from rkmpc.analysis.plots import save_figure
    from rkmpc.core.io import check_output_folder, output_folder, write_json_atomic, write_text_atomic
    from rkmpc.experiments.evaluate import evaluate
    from rkmpc.learning.io import load_any_model

    markers = ("evaluation.json",)
    check_output_folder(args.out, force=args.force, markers=markers)
    car = car_config(args)
    data, source = _data(args, car)
    models = {Path(path).name: load_any_model(path) for path in args.model}
    result = evaluate(
        data,
        models,
        car.vehicle,
        horizons=ints(args.horizons, "--horizons"),
        estimator=car.estimator,
        rkmpc=car.controllers.rkmpc,
        source=source,
    )
    text = result.to_markdown()
    with output_folder(args.out, force=args.force, markers=markers) as out:
        write_json_atomic(out / "evaluation.json", result.to_json())
        write_text_atomic(out / "evaluation.md", text)
    print(text)
    save_figure(result.figure(), args.out / "evaluation.png")
    return 0
