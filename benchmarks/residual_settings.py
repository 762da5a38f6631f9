"""The residual MPC's optional settings on one track and some cars: steering-rate weight, trust guard.

For each car (``none`` for the project's own plant, else a zoo variant) the script learns the
``rkmpc`` model from two LMPC laps of that car (through the model cache), drives the LMPC, then
``rkmpc`` with each setting, and prints the changes against the LMPC and the trust guard's counts.
The figures of issue 11's note came from ``python benchmarks/residual_settings.py builtin none,gym``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from scenarios import with_controllers

from rkmpc.control.learned.rkmpc import ResidualKoopmanMPC
from rkmpc.control.learned.trust import TrustConfig
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import load_scenario

KEYS = ("lateral_error_mean_m", "heading_error_mean_rad", "lateral_error_max_m", "command_rate_mean_rad_s")


def main(track: str, cars: list[str]) -> None:
    base = replace(ResidualKoopmanMPC.default_config, trust=TrustConfig(enabled=False))
    variants = {
        "plain": base,
        "rate 1": replace(base, steer_rate_weight=1.0),
        "rate 5": replace(base, steer_rate_weight=5.0),
        "trust": replace(base, trust=TrustConfig()),
        "rate 5 + trust": replace(base, steer_rate_weight=5.0, trust=TrustConfig()),
    }
    print("| car | setting | lat (m) | lat / head / max / cmd rate vs LMPC | faded steps |")
    print("|---|---|---|---|---|")
    for car in cars:
        scenario = load_scenario(track, car=None if car == "none" else car)
        models, _ = learn_models(scenario, ModelPlan(controllers=("rkmpc",)))
        _, lmpc = run_controller(scenario, RunSpec("lmpc"))
        for name, config in variants.items():
            result, m = run_controller(
                with_controllers(scenario, rkmpc=config), RunSpec("rkmpc"), model=models["rkmpc"]
            )
            if not (m.completed and lmpc.completed):
                print(f"| {car} | {name} | off at {m.progress:.0%} | - | - |", flush=True)
                continue
            changes = " / ".join(f"{100 * (m[k] - lmpc[k]) / lmpc[k]:+.0f}%" for k in KEYS)
            faded = result.diagnostics["trust_faded_range"] + result.diagnostics["trust_faded_error"]
            print(f"| {car} | {name} | {m.lateral_error_mean_m:.4f} | {changes} | {faded:.0f} |", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("track", nargs="?", default="builtin", help="built-in name or centre-line CSV")
    parser.add_argument(
        "cars", nargs="?", default="none,gym", help="comma-separated zoo cars (none: the project's plant)"
    )
    args = parser.parse_args()
    main(args.track, args.cars.split(","))
