"""Benchmark the per-step time of each controller over a real lap.

Run: ``make bench`` (or ``python benchmarks/bench_step.py --out FILE``). Each
controller drives one lap of the track in closed loop with the simulated car;
the step time is the controller's own wall-clock time per call, as logged.
Reports whether the lap was completed (else how much of it), the fall-backs, and the
median, mean, p99 and max step time in ms, and writes JSON. The nonlinear MPCs' real-time
paths are rows of their own: one SQP iteration per step (``sqp, 1 it``) and, where the
extra ``rkmpc[acados]`` is installed (``make bench`` installs it), the acados RTI.
"""

from __future__ import annotations

import os

# One thread per process: small dense algebra is slower with thread pools.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import importlib.util
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scenarios import with_controllers

from rkmpc.core.errors import IdentificationWarning
from rkmpc.core.io import write_json_atomic
from rkmpc.core.versions import versions
from rkmpc.experiments.compare import CompareConfig
from rkmpc.experiments.models import learn_models
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import Scenario, load_scenario

SHARED_MONZA = Path(__file__).resolve().parents[1].parent / "shared" / "tracks" / "centerlines" / "Monza.csv"

#: A benchmark case: label, controller name, changes to the car's controller settings (by section
#: attribute: ``{"lmpc": {"solver": "osqp"}}``), and the model of a learned controller.
Case = tuple[str, str, dict[str, dict[str, Any]], object]

#: The controllers that need no training.
CASES: tuple[Case, ...] = (
    ("pp", "pp", {}, None),
    ("lmpc (daqp)", "lmpc", {"lmpc": {"solver": "daqp"}}, None),
    ("lmpc (osqp)", "lmpc", {"lmpc": {"solver": "osqp"}}, None),
    ("lmpc (daqp, plan)", "lmpc", {"lmpc": {"solver": "daqp", "linearisation": "plan"}}, None),
    ("nmpc (ipopt)", "nmpc", {}, None),
    ("nmpc (sqp, 1 it)", "nmpc", {"nmpc": {"solver": "sqpmethod", "max_iterations": 1}}, None),
    ("nmpc-dyn (ipopt)", "nmpc-dynamic", {}, None),
    ("nmpc-dyn (sqp, 1 it)", "nmpc-dynamic", {"nmpc": {"solver": "sqpmethod", "max_iterations": 1}}, None),
)
#: The acados real-time iterations (the optional extra ``rkmpc[acados]``; `make bench` installs it).
ACADOS_CASES: tuple[Case, ...] = (
    ("nmpc-acados (rti)", "nmpc-acados", {}, None),
    ("nmpc-acados-dyn (rti)", "nmpc-acados-dynamic", {}, None),
)


def with_settings(scenario: Scenario, changes: dict[str, dict[str, Any]]) -> Scenario:
    """The scenario whose car has some controller settings changed (the reference stays)."""
    settings = scenario.car.controllers
    return with_controllers(scenario, **{s: replace(getattr(settings, s), **c) for s, c in changes.items()})


def learned_cases(scenario: Scenario, kmpc_model: Path | None) -> tuple[list[Case], list[str]]:
    """Learn as ``rkmpc compare`` does: two LMPC laps of the track, models from the cache when there.

    Returns the cases of the controllers learned, and the identification's warnings.
    """
    names = ("lmpc-id", "nmpc-id", "rkmpc", "rkmpc-paper", "kmpc")
    study = CompareConfig(
        track=scenario.track.source or scenario.track.name,
        car=scenario.car,
        controllers=names,
        model_files=() if kmpc_model is None else (("kmpc", str(kmpc_model)),),
    )
    # Identification keeping a servo or the tyres nominal on these laps is right, but a warning per
    # fit buries the table: as the CLI does, they are read from the models' records instead,
    # counted here and written to the JSON (``learning_warnings``).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        models, training = learn_models(scenario, study.plan())
    identified = [r.identified for r in training.models.values() if r.identified is not None]
    told = [w for model in identified for w in model.every_warning]
    if told:
        print(f"{len(told)} identification warnings while learning (kept nominal; in the JSON): {told[0]}")
    for name in names:
        if name not in models:
            print(f"{name}: not learned, not benchmarked: {training.models[name].refused}")
    return [(name, name, {}, models[name]) for name in names if name in models], told


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--track", default=str(SHARED_MONZA) if SHARED_MONZA.exists() else "builtin")
    parser.add_argument("--out", type=Path, default=Path("runs/bench/step_times.json"))
    parser.add_argument("--no-learned", action="store_true", help="skip the controllers that need training")
    parser.add_argument(
        "--kmpc-model",
        type=Path,
        default=None,
        help="a trained koopman model for KMPC (default: trained once, then cached)",
    )
    args = parser.parse_args()
    scenario = load_scenario(args.track)
    cases = list(CASES)
    if importlib.util.find_spec("acados") is not None:
        cases += ACADOS_CASES
    else:
        print("acados is not installed (`make acados`): the nmpc-acados rows are left out")
    told: list[str] = []
    if not args.no_learned:
        learned, told = learned_cases(scenario, args.kmpc_model)
        cases += learned
    # Other jobs on the machine change the times (the medians least): the load is recorded with them.
    report: dict[str, object] = {
        "track": scenario.track.name,
        "versions": versions(),
        "load_average_before": list(os.getloadavg()),
        "controllers": {},
    }
    print(f"track {scenario.track.name}, {scenario.reference.path.length:.1f} m")
    print(
        f"{'controller':22s} {'lap':>4s} {'fallbacks':>9s} {'steps':>6s} "
        f"{'median':>8s} {'mean':>8s} {'p99':>8s} {'max':>8s}  (ms)"
    )
    for label, name, changes, model in cases:
        runs_in = with_settings(scenario, changes)
        result, metrics = run_controller(runs_in, RunSpec(controller=name), model=model)
        ms = 1e3 * result.log["solve_time_s"]
        ms = ms[np.isfinite(ms)]
        stats = {
            "steps": int(ms.size),
            "completed": metrics["completed"],
            "progress": float(metrics["progress"]),
            "fallbacks": int(metrics["fallback_count"]),
            "lateral_error_mean_m": float(metrics["lateral_error_mean_m"]),
            "median_ms": float(np.median(ms)),
            "mean_ms": float(ms.mean()),
            "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max()),
        }
        report["controllers"][label] = stats  # type: ignore[index]
        lap = "yes" if stats["completed"] else f"{100 * stats['progress']:.0f}%"
        print(
            f"{label:22s} {lap:>4s} {stats['fallbacks']:9d} {stats['steps']:6d} {stats['median_ms']:8.3f} "
            f"{stats['mean_ms']:8.3f} {stats['p99_ms']:8.3f} {stats['max_ms']:8.3f}"
        )
    report["learning_warnings"] = told
    report["load_average_after"] = list(os.getloadavg())
    before, after = report["load_average_before"], report["load_average_after"]
    print(f"load average (1, 5, 15 min): before {before}, after {after}")
    write_json_atomic(args.out, report)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
