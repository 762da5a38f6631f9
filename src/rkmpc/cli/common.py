"""What the command-line modules share: argument groups and parsers of lists."""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path

__all__ = [
    "CACHE_HELP",
    "VEHICLES",
    "add_force_arg",
    "add_parallel_args",
    "at_least",
    "ints",
    "split_controllers",
]

VEHICLES = ["f1tenth", "fullsize"]
CACHE_HELP = "trained-model cache (default: $RKMPC_CACHE_DIR, else ~/.cache/rkmpc)"


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
