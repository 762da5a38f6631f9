"""What the command-line modules share: argument groups and parsers of lists."""

from __future__ import annotations

import argparse
import math
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rkmpc.config.car import CarConfig

__all__ = [
    "CACHE_HELP",
    "CONTROLLERS_HELP",
    "SCALE_HELP",
    "VEHICLES",
    "PaceWarning",
    "add_config_args",
    "add_force_arg",
    "add_ladder_args",
    "add_learning_args",
    "add_mismatch_arg",
    "add_parallel_args",
    "add_scenario_args",
    "at_least",
    "car_config",
    "ints",
    "ladder_from_args",
    "positive_float",
    "split_controllers",
]

VEHICLES = ["f1tenth", "fullsize"]


class PaceWarning(UserWarning):
    """The pace asked for is beyond what the car can do (:meth:`rkmpc.config.car.CarConfig.check_limits`)."""


CACHE_HELP = (
    "trained-model cache (default: $RKMPC_CACHE_DIR, else $XDG_CACHE_HOME/rkmpc, else ~/.cache/rkmpc)"
)
SCALE_HELP = "scale of track files (default: the car's, 0.1 for f1tenth, 1 for fullsize)"
CONTROLLERS_HELP = "comma-separated controller names"


def at_least(low: int) -> Callable[[str], int]:
    """An argparse ``type``: an integer >= ``low``; argparse names the option in its error."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value}")
        return value

    return parse


def add_force_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace the --out folder of an earlier run as a whole (refused otherwise)",
    )


def add_parallel_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--jobs", type=at_least(-1), default=os.cpu_count() or 1, help="parallel jobs (default: cores)"
    )
    parser.add_argument("--backend", default="loky", choices=["loky", "dask", "ray"], help="where jobs run")
    parser.add_argument("--address", default=None, help="scheduler address of a running dask or ray cluster")
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    add_force_arg(parser)


def split_controllers(text: str) -> list[str]:
    from rkmpc.control.registry import CONTROLLERS

    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in CONTROLLERS]
    if unknown or not names:
        raise ValueError(f"unknown controller(s) {unknown}; known: {sorted(CONTROLLERS)}")
    return names


def ints(text: str, what: str) -> tuple[int, ...]:
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ValueError(f"{what} must be comma-separated integers, got {text!r}") from None


def positive_float(text: str) -> float:
    """An argparse ``type``: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"must be finite and > 0, got {text!r}")
    return value


def add_config_args(parser: argparse.ArgumentParser, *, pace: bool = True) -> None:
    """``--config FILE`` (a car file) and, with ``pace``, ``--lateral-accel`` and ``--max-speed``."""
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="CAR.toml",
        help="car file: vehicle, plant, speed limits, controllers, training (options given here win)",
    )
    parser.add_argument(
        "--vehicle",
        default=None,
        choices=VEHICLES,
        help="vehicle preset; else the --config file's (default: f1tenth)",
    )
    parser.add_argument(
        "--sensors",
        default=None,
        metavar="PROFILE",
        help="what the simulated car measures: ideal, no-steer, f1tenth-real (a real F1TENTH car: no "
        "wheel angle, a late noisy localiser); else the --config file's [sensors] (default: ideal; "
        "study cars and car-loop: f1tenth-real)",
    )
    if pace:
        parser.add_argument(
            "--lateral-accel",
            type=positive_float,
            default=None,
            metavar="A",
            help="the pace: lateral-acceleration limit (m/s^2); braking and traction scale with it",
        )
        parser.add_argument(
            "--max-speed", type=positive_float, default=None, metavar="V", help="the pace: top speed (m/s)"
        )


def car_config(args: argparse.Namespace) -> CarConfig:
    """The effective car: the preset, then the ``--config`` file, then the options (flag > file > preset).

    The training settings (``--seed``, ``--epochs``, ``--data-laps``, ``--kmpc-samples``) and the
    zoo car (``--car``) given on the command line replace the file's; the pace
    (``--lateral-accel``, ``--max-speed``) is applied last (:meth:`SpeedLimits.at_pace`).
    """
    from rkmpc.config.loader import load_car_config, load_preset

    given = getattr(args, "config", None)
    vehicle = getattr(args, "vehicle", None)
    if given is None:
        config = load_preset(vehicle or "f1tenth")
    else:
        config = load_car_config(given)
        if vehicle is not None and vehicle != config.preset:
            raise ValueError(
                f"--vehicle {vehicle} contradicts {given}: its [vehicle] preset is {config.preset!r}"
            )
    names = ("seed", "epochs", "data_laps", "kmpc_samples")
    changes = {name: getattr(args, name) for name in names if getattr(args, name, None) is not None}
    config = config.with_training(**changes)
    car = getattr(args, "car", None)
    if car is not None:
        config = config.with_zoo_car(car)
    config = config.with_sensors(getattr(args, "sensors", None))
    config = config.at_pace(getattr(args, "lateral_accel", None), getattr(args, "max_speed", None))
    for doubt in config.check_limits():
        warnings.warn(doubt, PaceWarning, stacklevel=2)
    return config


def _pace(text: str, what: str) -> tuple[float, float]:
    parts = text.strip().split(":")
    try:
        lateral, speed = (float(v) for v in parts)
    except ValueError:
        raise ValueError(f"{what}: a pace is LATERAL:SPEED (m/s^2:m/s), e.g. 4:3.5, got {text!r}") from None
    return lateral, speed


def add_ladder_args(parser: argparse.ArgumentParser) -> None:
    """``--paces`` or ``--start/--step/--steps``: the pace ladder (lateral limit : top speed)."""
    parser.add_argument(
        "--paces",
        default=None,
        help="the ladder as LATERAL:SPEED pairs, e.g. 4:3.5,5:4.5 (default: from --start, --step, --steps)",
    )
    parser.add_argument(
        "--start",
        default=None,
        help="first pace LATERAL:SPEED (default: the car's own, the --config file's [limits], "
        "else the vehicle preset's: 4:3.5 for f1tenth)",
    )
    parser.add_argument(
        "--step",
        default=None,
        help="pace step LATERAL:SPEED (default: 0.5:0.5 for f1tenth; top speed capped at the car's)",
    )
    parser.add_argument(
        "--steps",
        type=at_least(0),
        default=None,
        help="steps above the first pace, at most 59 (default: 40 for f1tenth, 16 for fullsize)",
    )


def ladder_from_args(args: argparse.Namespace, car: CarConfig) -> tuple[tuple[float, float], ...]:
    """The ladder the ``add_ladder_args`` options ask for, of ``car`` (:func:`car_config`).

    Without ``--paces`` or ``--start`` it starts at the car's own pace (its limits: the
    ``--config`` file's, else the preset's) and is capped at the car's top speed.
    """
    from rkmpc.experiments.studies.pace_rules import car_ladder, check_ladder

    if args.paces is not None:
        if args.start is not None or args.step is not None or args.steps is not None:
            raise ValueError("give either --paces or --start/--step/--steps, not both")
        return check_ladder("--paces", [_pace(t, "--paces") for t in args.paces.split(",") if t.strip()])
    return car_ladder(
        car,
        start=None if args.start is None else _pace(args.start, "--start"),
        step=None if args.step is None else _pace(args.step, "--step"),
        steps=args.steps,
    )


def add_scenario_args(
    parser: argparse.ArgumentParser,
    out_help: str = "output folder",
    laps_help: str = "laps each controller drives",
) -> None:
    """The track, the car and the run: what ``run``, ``compare`` and ``collect`` share."""
    parser.add_argument("--track", default="builtin", help="built-in track name or TUM centre-line CSV")
    parser.add_argument(
        "--raceline", default=None, help="TUM race-line CSV to track instead of the centre line"
    )
    parser.add_argument("--scale", type=float, default=None, help=SCALE_HELP)
    add_config_args(parser)
    parser.add_argument(
        "--car", default=None, help="drive a car of the zoo (gym, overshoot, ..., random-<seed>) instead"
    )
    parser.add_argument("--laps", type=at_least(1), default=1, help=laps_help)
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
        help=(
            "model file of a learned controller (rkmpc, rkmpc-paper, kmpc, lmpc-id, nmpc-id); "
            "repeat as NAME=PATH"
        ),
    )


def add_learning_args(parser: argparse.ArgumentParser) -> None:
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
    add_mismatch_arg(parser, "drive with --model files made with another car, period or track scale")
    add_force_arg(parser)


def add_mismatch_arg(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument(
        "--allow-mismatch", action="store_true", help=f"{what} (refused otherwise; the results record it)"
    )
