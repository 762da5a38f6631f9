"""Benchmark the per-step time of each controller over a real lap.

Run: ``make bench`` (or ``python benchmarks/bench_step.py --out FILE``). Each
controller drives one lap of the track in closed loop with the simulated car;
the step time is the controller's own wall-clock time per call, as logged.
Reports median, mean, p99 and max in ms and writes JSON.
"""

from __future__ import annotations

import os

# One thread per process: small dense algebra is slower with thread pools.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import importlib.util
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.nonlinear.nmpc import NMPCConfig
from rkmpc.core.io import write_json_atomic
from rkmpc.core.versions import versions
from rkmpc.experiments.compare import CompareConfig
from rkmpc.experiments.models import learn_models
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import Scenario, load_scenario

SHARED_MONZA = Path(__file__).resolve().parents[1].parent / "shared" / "tracks" / "centerlines" / "Monza.csv"

#: (label, controller name, options) of the controllers that need no training.
CASES = (
    ("pp", "pp", {}),
    ("lmpc (daqp)", "lmpc", {"config": LMPCConfig(solver="daqp")}),
    ("lmpc (osqp)", "lmpc", {"config": LMPCConfig(solver="osqp")}),
    ("nmpc (ipopt)", "nmpc", {}),
    ("nmpc (sqp, 1 it)", "nmpc", {"config": NMPCConfig(solver="sqpmethod", max_iterations=1)}),
    ("nmpc-dyn (ipopt)", "nmpc-dynamic", {}),
    ("nmpc-dyn (sqp, 1 it)", "nmpc-dynamic", {"config": NMPCConfig(solver="sqpmethod", max_iterations=1)}),
)


def learned_cases(scenario: Scenario, kmpc_model: Path | None) -> list[tuple[str, str, dict[str, Any]]]:
    """Learn as ``rkmpc compare`` does: two LMPC laps of the track, models from the cache when there."""
    names = ("lmpc-id", "rkmpc", "rkmpc-paper", "kmpc")
    study = CompareConfig(
        track=scenario.track.source or scenario.track.name,
        controllers=names,
        kmpc_model=None if kmpc_model is None else str(kmpc_model),
    )
    options, _ = learn_models(scenario, study.plan())
    return [(name, name, options[name]) for name in names]


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
        cases.append(("nmpc-acados (rti)", "nmpc-acados", {}))
        cases.append(("nmpc-acados-dyn (rti)", "nmpc-acados-dynamic", {}))
    if not args.no_learned:
        cases += learned_cases(scenario, args.kmpc_model)
    report: dict[str, object] = {"track": scenario.track.name, "versions": versions(), "controllers": {}}
    print(f"track {scenario.track.name}, {scenario.reference.path.length:.1f} m")
    print(f"{'controller':20s} {'steps':>6s} {'median':>8s} {'mean':>8s} {'p99':>8s} {'max':>8s}  (ms)")
    for label, name, options in cases:
        result, metrics = run_controller(scenario, RunSpec(controller=name), controller_options=options)
        ms = 1e3 * result.log["solve_time_s"]
        ms = ms[np.isfinite(ms)]
        stats = {
            "steps": int(ms.size),
            "completed": metrics["completed"],
            "median_ms": float(np.median(ms)),
            "mean_ms": float(ms.mean()),
            "p99_ms": float(np.percentile(ms, 99)),
            "max_ms": float(ms.max()),
        }
        report["controllers"][label] = stats  # type: ignore[index]
        print(
            f"{label:20s} {stats['steps']:6d} {stats['median_ms']:8.3f} {stats['mean_ms']:8.3f} "
            f"{stats['p99_ms']:8.3f} {stats['max_ms']:8.3f}"
        )
    write_json_atomic(args.out, report)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
