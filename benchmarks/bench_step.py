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

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from rkmpc.control.lmpc import LMPCConfig  # noqa: E402
from rkmpc.experiments.runner import RunSpec, run_controller, versions  # noqa: E402
from rkmpc.scenario import load_scenario  # noqa: E402
from rkmpc.sim.log import write_json_atomic  # noqa: E402

SHARED_MONZA = Path(__file__).resolve().parents[1].parent / "shared" / "tracks" / "centerlines" / "Monza.csv"

#: (label, controller name, options)
CASES = (
    ("pp", "pp", {}),
    ("lmpc (daqp)", "lmpc", {"config": LMPCConfig(solver="daqp")}),
    ("lmpc (osqp)", "lmpc", {"config": LMPCConfig(solver="osqp")}),
)


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--track", default=str(SHARED_MONZA) if SHARED_MONZA.exists() else "builtin")
    parser.add_argument("--out", type=Path, default=Path("runs/bench/step_times.json"))
    args = parser.parse_args()
    scenario = load_scenario(args.track)
    report: dict[str, object] = {"track": scenario.track.name, "versions": versions(), "controllers": {}}
    print(f"track {scenario.track.name}, {scenario.reference.path.length:.1f} m")
    print(f"{'controller':14s} {'steps':>6s} {'median':>8s} {'mean':>8s} {'p99':>8s} {'max':>8s}  (ms)")
    for label, name, options in CASES:
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
            f"{label:14s} {stats['steps']:6d} {stats['median_ms']:8.3f} {stats['mean_ms']:8.3f} "
            f"{stats['p99_ms']:8.3f} {stats['max_ms']:8.3f}"
        )
    write_json_atomic(args.out, report)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
