"""Drive PP and LMPC around every shared track and tabulate the metrics.

Run: ``make tracks-table`` (or ``python benchmarks/tracks_table.py --out DIR``).
Uses the TUM tracks in ``../shared/tracks/centerlines`` at scale 0.1 with the
f1tenth plant; runs tracks in parallel processes (one per core). Writes
``DIR/tracks.json`` and ``DIR/tracks.md``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

from scenarios import with_controllers

from rkmpc.analysis.tables import TABLE_COLUMNS, format_cell
from rkmpc.core.io import write_json_atomic, write_text_atomic
from rkmpc.core.versions import versions
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import load_scenario

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "tracks" / "centerlines"


#: ``--nmpc-sqp``: the nonlinear MPCs on their fast path, one SQP iteration per step.
FAST_NMPC = {"solver": "sqpmethod", "max_iterations": 1}


def run_track(job: tuple[str, str, float, bool]) -> tuple[str, str, dict[str, Any]]:
    """Run one controller on one track (a worker job)."""
    track, controller, scale, nmpc_sqp = job
    scenario = load_scenario(track, scale=scale)
    if nmpc_sqp and controller.startswith("nmpc"):
        scenario = with_controllers(scenario, nmpc=replace(scenario.car.controllers.nmpc, **FAST_NMPC))
    _result, metrics = run_controller(scenario, RunSpec(controller=controller))
    return scenario.track.name, controller, metrics.to_json()


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tracks", type=Path, default=SHARED)
    parser.add_argument("--controllers", default="pp,lmpc")
    parser.add_argument("--scale", type=float, default=0.1)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--nmpc-sqp", action="store_true", help="NMPCs with one SQP iteration per step")
    parser.add_argument("--out", type=Path, default=Path("runs/tracks"))
    args = parser.parse_args()
    files = sorted(args.tracks.glob("*.csv"))
    controllers = args.controllers.split(",")
    jobs = [("builtin", c, 1.0, args.nmpc_sqp) for c in controllers]
    jobs += [(str(f), c, args.scale, args.nmpc_sqp) for f in files for c in controllers]
    table: dict[str, dict[str, dict[str, Any]]] = {}
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for track, controller, metrics in pool.map(run_track, jobs):
            table.setdefault(track, {})[controller] = metrics
            print(
                f"{track:14s} {controller:6s} done={metrics['completed']!s:5s} "
                f"lat={format_cell(metrics['lateral_error_mean_m'], '{:.4f}')} "
                f"head={format_cell(metrics['heading_error_mean_rad'], '{:.4f}')} "
                f"rate={format_cell(metrics['steer_rate_mean_rad_s'], '{:.4f}')}",
                flush=True,
            )
    args.out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(
        args.out / "tracks.json", {"tracks": table, "scale": args.scale, "versions": versions()}
    )
    header = ["track", "controller"] + [title for _, title, _ in TABLE_COLUMNS]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for track, per in table.items():
        for controller, metrics in per.items():
            cells = [format_cell(metrics[k], fmt) for k, _, fmt in TABLE_COLUMNS]
            lines.append("| " + " | ".join([track, controller, *cells]) + " |")
    write_text_atomic(args.out / "tracks.md", "\n".join(lines) + "\n")
    print(f"wrote {args.out / 'tracks.md'}")


if __name__ == "__main__":
    main()
