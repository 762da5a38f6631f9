"""The out-of-distribution guard and online adaptation of ``rkmpc``, against the fixed model.

For each case (a fault on the project's car, or a car of the zoo) the residual model is learned
from two LMPC laps of the nominal situation (for a zoo car: of that car), then one lap each is
driven by the LMPC, ``rkmpc`` as trained, ``rkmpc`` with the trust guard, ``rkmpc`` with online
adaptation (recursive least squares on its output map) and with both. A fault is applied to the
driven lap only, so the model meets a car it was not trained on. Prints a Markdown table and
writes the figures as JSON.

Run: ``python benchmarks/robustness.py --track builtin --out runs/robustness/robustness.json``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

from scenarios import with_controllers

from rkmpc.config.loader import load_preset
from rkmpc.control.learned.adaptation import AdaptationConfig
from rkmpc.control.learned.trust import TrustConfig
from rkmpc.core.io import write_json_atomic
from rkmpc.core.versions import versions
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import load_scenario

#: rkmpc's settings on the 1:10 car (the f1tenth preset's: the controller's defaults).
RKMPC_CONFIG = load_preset("f1tenth").controllers.rkmpc

#: (label, fault, car) of each case.
CASES = (
    ("friction drop", "friction", None),
    ("heavy car", "heavy", None),
    ("delay", "delay", None),
    ("zoo: gym", None, "gym"),
    ("zoo: heavy-long", None, "heavy-long"),
    ("zoo: low-grip", None, "low-grip"),
)

#: The rkmpc settings compared, by label.
VARIANTS = {
    "fixed": replace(RKMPC_CONFIG, trust=TrustConfig(enabled=False)),
    "trust": replace(RKMPC_CONFIG, trust=TrustConfig()),
    "adapt": replace(
        RKMPC_CONFIG, trust=TrustConfig(enabled=False), adaptation=AdaptationConfig(enabled=True)
    ),
    "trust+adapt": replace(RKMPC_CONFIG, trust=TrustConfig(), adaptation=AdaptationConfig(enabled=True)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--track", default="builtin")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True, help="JSON file")
    args = parser.parse_args()
    rows: list[dict[str, Any]] = []
    head = [
        "case",
        "lmpc lat (m)",
        *(f"{v} lat (m)" for v in VARIANTS),
        *(f"{v} faded / learned" for v in VARIANTS),
    ]
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head), flush=True)
    for label, fault, car in CASES:
        scenario = load_scenario(args.track, car=car)
        models, _ = learn_models(scenario, ModelPlan(controllers=("rkmpc",), seed=args.seed))
        _, lmpc = run_controller(scenario, RunSpec("lmpc", seed=args.seed, fault=fault))
        runs: dict[str, Any] = {}
        for name, config in VARIANTS.items():
            result, metrics = run_controller(
                with_controllers(scenario, rkmpc=config),
                RunSpec("rkmpc", seed=args.seed, fault=fault),
                model=models["rkmpc"],
            )
            runs[name] = {"metrics": metrics.to_json(), "diagnostics": result.diagnostics}
        rows.append({"case": label, "fault": fault, "car": car, "lmpc": lmpc.to_json(), "rkmpc": runs})
        print(_line(label, lmpc.to_json(), runs), flush=True)
    write_json_atomic(
        args.out, {"track": args.track, "seed": args.seed, "rows": rows, "versions": versions()}
    )


def _lat(metrics: dict[str, Any]) -> str:
    if not metrics["completed"]:
        return f"off at {metrics['progress']:.0%}"
    return f"{metrics['lateral_error_mean_m']:.4f}"


def _line(label: str, lmpc: dict[str, Any], runs: dict[str, Any]) -> str:
    cells = [label, _lat(lmpc), *(_lat(run["metrics"]) for run in runs.values())]
    for run in runs.values():
        d = run["diagnostics"]
        faded = d["trust_faded_range"] + d["trust_faded_error"] if "trust_steps" in d else 0.0
        cells.append(f"{faded:.0f} / {d['rls_updates']:.0f}" if "rls_updates" in d else f"{faded:.0f} / -")
    return "| " + " | ".join(cells) + " |"


if __name__ == "__main__":
    main()
