"""``rkmpc train``: a model of any kind from a data set, saved to a file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rkmpc.cli.common import add_config_args, add_mismatch_arg, at_least, car_config

__all__ = ["add_train_parser", "cmd_train"]


def add_train_parser(sub: Any) -> None:
    from rkmpc.learning.recipes import model_kinds

    train = sub.add_parser("train", help="train a model from a data set")
    train.add_argument(
        "--data", required=True, type=Path, help="the data set (.npz, from rkmpc collect) to learn from"
    )
    train.add_argument(
        "--kind",
        required=True,
        choices=model_kinds(),
        help="the model: residual (rkmpc), paper (rkmpc-paper), koopman (kmpc), identified (lmpc-id)",
    )
    add_config_args(train, pace=False)  # the car the model is for
    train.add_argument("--dt", type=float, default=0.05, help="control period the model is for (s)")
    add_mismatch_arg(train, "train on data recorded with another car or period")
    train.add_argument(
        "--epochs", type=at_least(1), default=None, help="else the --config file's, else the recipe's"
    )
    train.add_argument("--seed", type=at_least(0), default=None, help="else the --config file's (default: 0)")
    train.add_argument("--out", required=True, type=Path, help="model file")


def cmd_train(args: argparse.Namespace) -> int:
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
            on_epoch=on_epoch if not args.kind.startswith("identified") else None,
            allow_mismatch=args.allow_mismatch,
            source=str(args.data),
            estimator=car.estimator,
        )
    print("\n".join(lines))
    return 0
