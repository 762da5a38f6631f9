"""Which baseline should the residual correct: ``rkmpc`` on the nominal LMPC or on ``lmpc-id``.

Issue 26 asks for the baseline MPC under the residual to be a choice. ``ResidualKoopmanMPC`` takes
any :class:`~rkmpc.control.linear.lmpc.LinearMPC` as its ``baseline``; this script drives, for each
car, sensor profile and track, one lap of the LMPC, ``lmpc-id``, ``rkmpc`` (the nominal LMPC under
the residual) and ``rkmpc`` on ``lmpc-id`` (the identified LMPC's plan corrected by the same
residual model and settings), every model learned from the same two LMPC laps through the model
cache, as ``rkmpc compare`` learns them. It prints mean and maximum lateral error (m), mean
heading error (rad) and commanded steering rate (rad/s), and writes them to a JSON file.

Run: ``python benchmarks/residual_baseline.py --tracks builtin,../shared/tracks/centerlines/Austin.csv
--cars home,gym,cheap-servo --sensors ideal,f1tenth-real --out runs/residual_baseline.json``
(``home``: the project's own car).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rkmpc.analysis.metrics import LapMetrics, lap_metrics
from rkmpc.config.loader import load_preset
from rkmpc.control.base import Controller
from rkmpc.control.estimated import EstimatedController
from rkmpc.control.learned.rkmpc import ResidualKoopmanMPC
from rkmpc.control.linear.lmpc_id import IdentifiedLMPC
from rkmpc.core.io import write_json_atomic
from rkmpc.core.versions import versions
from rkmpc.experiments.compare import CompareConfig
from rkmpc.experiments.models import learn_models
from rkmpc.sim.build import build_controller, make_estimator
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.run import RunSpec, build_plant
from rkmpc.sim.scenario import Scenario

#: The rows of each case, in this order.
ROWS = ("lmpc", "lmpc-id", "rkmpc", "rkmpc on lmpc-id")


def rkmpc_on_lmpc_id(scenario: Scenario, models: dict[str, object]) -> Controller:
    """``rkmpc`` with the car's settings whose residual corrects ``lmpc-id``'s plan."""
    settings = scenario.car.controllers.with_period(scenario.dt)
    baseline = IdentifiedLMPC(scenario.reference, scenario.vehicle, models["lmpc-id"], settings.lmpc)
    controller = ResidualKoopmanMPC(
        scenario.reference,
        scenario.vehicle,
        models["rkmpc"],
        config=settings.rkmpc,
        baseline=baseline,
    )
    if scenario.car.sensors.is_ideal:
        return controller
    return EstimatedController(controller, make_estimator(scenario, models["rkmpc"]))


def drive(scenario: Scenario, controller: Controller, seed: int) -> LapMetrics:
    """One lap of ``controller`` on the scenario's plant and sensors."""
    plant = build_plant(scenario, RunSpec(controller.name, laps=1, seed=seed))
    result = simulate(
        plant, controller, scenario.track, scenario.reference, SimConfig(dt=scenario.dt, laps=1)
    )
    return lap_metrics(result)


def case(track: str, car: str, sensors: str, seed: int) -> dict[str, Any]:
    """The four controllers on one track, car and sensor profile."""
    zoo = None if car == "home" else car
    config = CompareConfig(
        track=track,
        car=load_preset("f1tenth").with_zoo_car(zoo).with_sensors(sensors),
        controllers=("lmpc", "lmpc-id", "rkmpc"),
    )
    scenario = config.scenario()
    models, _ = learn_models(scenario, config.plan())
    row: dict[str, Any] = {"track": scenario.track.name, "car": car, "sensors": sensors}
    for name in ROWS[:3]:
        row[name] = drive(scenario, build_controller(name, scenario, models.get(name)), seed).to_json()
    row[ROWS[3]] = drive(scenario, rkmpc_on_lmpc_id(scenario, models), seed).to_json()
    return row


def _line(row: dict[str, Any]) -> str:
    cells = []
    for name in ROWS:
        m = row[name]
        done = "" if m["completed"] else f" (DNF {100 * m['progress']:.0f}%)"
        cells.append(
            f"{m['lateral_error_mean_m']:.4f} / {m['lateral_error_max_m']:.3f} / "
            f"{m['heading_error_mean_rad']:.4f} / {m['command_rate_mean_rad_s']:.3f}{done}"
        )
    return f"| {row['car']} | {row['sensors']} | {row['track']} | " + " | ".join(cells) + " |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tracks", default="builtin", help="comma-separated tracks (built-in names or CSV files)"
    )
    parser.add_argument("--cars", default="home", help="comma-separated zoo cars, 'home' for the own car")
    parser.add_argument("--sensors", default="ideal", help="comma-separated sensor profiles")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True, help="JSON file")
    args = parser.parse_args()
    print("| car | sensors | track | " + " | ".join(ROWS) + " |")
    print("|---|---|---|" + "---|" * len(ROWS))
    rows = []
    for car in args.cars.split(","):
        for sensors in args.sensors.split(","):
            for track in args.tracks.split(","):
                rows.append(case(track, car, sensors, args.seed))
                print(_line(rows[-1]), flush=True)
    write_json_atomic(
        args.out,
        {
            "seed": args.seed,
            "cells": "lateral mean / max (m), heading (rad), command rate (rad/s)",
            "rows": rows,
            "versions": versions(),
        },
    )


if __name__ == "__main__":
    main()
