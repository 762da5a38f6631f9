"""How much of a controller's heading error is the car's side-slip: heading against course error.

The lap metrics' heading error is the car's *yaw* against the path's tangent. A car whose centre of
gravity runs exactly along the path points its velocity along the tangent, so its yaw differs from
the tangent by its side-slip angle ``beta`` (velocity direction minus heading): even a perfect
tracker has a heading error of about ``|beta|``. The *course* error, the velocity's direction
against the tangent (``heading error + beta``), is the part that moves the car off the path.

Reads the step logs a comparison writes (``log_<controller>.csv`` and its ``.meta.json``, e.g.
``runs/demo`` of ``make demo``; the plant's true side-slip is the ``state_beta`` column) and prints,
over each controller's first lap: mean lateral error (m), mean heading error (rad), mean ``|beta|``
(rad) and mean course error (rad).

Run: ``python benchmarks/heading_vs_course.py runs/demo [runs/demo/sensors-f1tenth-real]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from compare_logs import first_laps

from rkmpc.sim.log import StepLog

#: Controllers shown, in this order, where their logs exist.
CONTROLLERS = ("lmpc", "lmpc-id", "nmpc-dynamic", "rkmpc")


def lap_figures(log: StepLog, first: np.ndarray) -> tuple[float, float, float, float]:
    """Mean |lateral error|, |heading error|, |beta| and |course error| over the steps ``first``."""
    heading = log["heading_error"][first]
    beta = log["state_beta"][first]
    return (
        float(np.mean(np.abs(log["lateral_error"][first]))),
        float(np.mean(np.abs(heading))),
        float(np.mean(np.abs(beta))),
        float(np.mean(np.abs(heading + beta))),
    )


def table(folder: Path) -> str:
    """The Markdown table of one comparison folder."""
    lines = [
        f"`{folder}`",
        "",
        "| controller | lateral (m) | heading (rad) | mean abs(beta) (rad) | course (rad) |",
        "|---|---|---|---|---|",
    ]
    for name, log, first in first_laps(folder, CONTROLLERS):
        if first is None:
            lines.append(f"| {name} | no lap completed | | | |")
            continue
        lateral, heading, beta, course = lap_figures(log, first)
        lines.append(f"| {name} | {lateral:.4f} | {heading:.4f} | {beta:.4f} | {course:.4f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path, help="comparison output folders (runs/demo)")
    args = parser.parse_args(argv)
    for folder in args.folders:
        sys.stdout.write(table(folder) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
