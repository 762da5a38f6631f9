"""The LMPC linearised about its own previous plan against the LMPC linearised along the reference.

The LMPC (:class:`rkmpc.control.linear.lmpc.LinearMPC`) linearises the kinematic bicycle along
the reference by default (the paper's MPC1): heading, speed and wheel angle of the path. Where the
car is off the path, or the path asks for more than the car can do, that is not where the car
will be. With ``[controllers.lmpc] linearisation = "plan"`` it linearises instead about the
previous step's plan, shifted by one step and rolled out from the measured pose, with the affine
term (the linear time-varying MPC of a real-time iteration); nothing else changes: same weights,
bounds, solver and deviation variables. This table drives both on each track. ``--linearisation
plan-midpoint`` drives the LMPC that rolls its plan out by the midpoint rule instead of forward
Euler (``docs/design.md``: most of what ``"plan"`` gains is the forward-Euler roll-out's).

Ideal sensors, the ``f1tenth`` preset's car and settings, seed 0, one lap.

Run: ``python benchmarks/plan_linearisation.py builtin ../shared/tracks/centerlines/*.csv``
(``--linearisation plan-midpoint`` for the midpoint roll-out).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np
from steering_limit import FRACTION, WINDOW, near, places_near_limit

from rkmpc.control.linear.lmpc import LINEARISATIONS, LinearMPC
from rkmpc.sim.build import build_controller
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.run import RunSpec, build_plant
from rkmpc.sim.scenario import Scenario, load_scenario


def lap(scenario: Scenario, controller: LinearMPC) -> tuple[str, np.ndarray, np.ndarray, float]:
    """Outcome, arc length (m) and |lateral error| (m) of every step, and the mean |heading error| (rad)."""
    plant = build_plant(scenario, RunSpec(controller="lmpc"))
    result = simulate(
        plant, controller, scenario.track, scenario.reference, SimConfig(dt=scenario.dt, laps=1)
    )
    log = result.log
    return (
        result.outcome,
        log["s"],
        np.abs(log["lateral_error"]),
        float(np.mean(np.abs(log["heading_error"]))),
    )


def row(track: str, linearisation: str) -> str:
    """One Markdown row: the LMPC and the LMPC with ``linearisation`` on ``track``."""
    scenario = load_scenario(track)
    lmpc = build_controller("lmpc", scenario)
    if not isinstance(lmpc, LinearMPC):
        raise TypeError(f"{track}: the f1tenth preset's lmpc is not a LinearMPC")
    plan = LinearMPC(scenario.reference, scenario.vehicle, replace(lmpc.config, linearisation=linearisation))
    hot = places_near_limit(scenario)
    cells = []
    for controller in (lmpc, plan):
        outcome, along, error, heading = lap(scenario, controller)
        close = near(along, hot, scenario.reference.path.length)
        near_mean = f"{error[close].mean():.4f}" if close.any() else "-"
        cells.append((outcome, error.mean(), error.max(), heading, near_mean, error[~close].mean()))
    (o1, m1, x1, h1, n1, a1), (o2, m2, x2, h2, n2, a2) = cells
    return (
        f"| {scenario.track.name} | {o1} / {o2} | {m1:.4f} / {m2:.4f} ({m2 / m1 - 1:+.0%}) "
        f"| {x1:.3f} / {x2:.3f} ({x2 / x1 - 1:+.0%}) | {h1:.4f} / {h2:.4f} ({h2 / h1 - 1:+.0%}) "
        f"| {n1} / {n2} | {a1:.4f} / {a2:.4f} |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tracks", nargs="+", help="built-in track names or centre-line CSV files")
    parser.add_argument(
        "--linearisation",
        choices=[name for name in LINEARISATIONS if name != "reference"],
        default="plan",
        help="the LMPC compared with the paper's (default: plan)",
    )
    args = parser.parse_args(argv)
    sys.stdout.write(
        f"LMPC / LMPC with linearisation {args.linearisation!r}, ideal sensors, one lap; near: within "
        f"{WINDOW:g} m of path beyond {FRACTION:g} of the steering limit\n\n"
        "| track | outcome | lateral mean (m) | lateral max (m) | heading mean (rad) | near (m) "
        "| away (m) |\n"
        "|---|---|---|---|---|---|---|\n"
    )
    for track in args.tracks:
        sys.stdout.write(row(track, args.linearisation) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
