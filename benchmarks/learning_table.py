"""LMPC, lmpc-id, rkmpc-paper, rkmpc and KMPC on the built-in and every shared track.

Run: ``make learning-table`` (or ``python benchmarks/learning_table.py --out DIR``).
For each track: two LMPC laps of data, the residual models trained on them,
lmpc-id identified from them, then one lap per controller. The KMPC model is
trained once on 50,000 random-excitation samples of the car (cached in DIR).
Tracks run in parallel processes. Writes ``DIR/learning.json`` and ``DIR/learning.md``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.analysis.statistics import change_pct
from rkmpc.control.learned.rkmpc import ResidualMPCConfig
from rkmpc.core.io import write_json_atomic
from rkmpc.experiments.compare import LEARNED_CONTROLLERS, RKMPC_CONFIG, CompareConfig, compare
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.sim.collect import collect_excitation
from rkmpc.sim.scenario import load_scenario

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "tracks" / "centerlines"
KEYS = (
    ("lateral_error_mean_m", "lat"),
    ("heading_error_mean_rad", "head"),
    ("steer_rate_mean_rad_s", "rate"),
)


def _job(study: CompareConfig) -> dict[str, Any]:
    import torch

    torch.set_num_threads(1)
    return compare(study).to_json()


def train_kmpc(out: Path, samples: int, seed: int) -> Path:
    """Train (or reuse) the KMPC model on random-excitation data."""
    path = out / f"kmpc_{samples}_{seed}.rkm"
    if path.exists():
        return path
    scenario = load_scenario("builtin")
    recipe = recipe_of_kind("koopman")
    data = collect_excitation(scenario, n_samples=samples, seed=seed)
    model, report = train_model(
        data,
        scenario.vehicle.wheelbase,
        TrainConfig(kind="koopman", augment=recipe.augment(seed), model=recipe.default_model(seed)),
    )
    model.save(path, metadata=model.metadata_)
    print(
        f"KMPC model: {report.raw_count} -> {report.augmented_count} samples, {report.fit_time_s:.1f} s",
        flush=True,
    )
    return path


def _change(a: float | None, b: float | None) -> str:
    change = change_pct(a, b)
    return "-" if change is None else f"{change:+.0f}%"


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tracks", type=Path, default=SHARED)
    parser.add_argument("--only", default="", help="comma-separated track names (builtin included by name)")
    parser.add_argument("--controllers", default=",".join(LEARNED_CONTROLLERS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--kmpc-samples", type=int, default=50_000)
    parser.add_argument("--rkmpc", default="{}", help="JSON overrides of the rkmpc residual MPC settings")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--out", type=Path, default=Path("runs/learning"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    controllers = tuple(args.controllers.split(","))
    kmpc = str(train_kmpc(args.out, args.kmpc_samples, args.seed)) if "kmpc" in controllers else None
    tracks = ["builtin"] + [str(f) for f in sorted(args.tracks.glob("*.csv"))]
    if args.only:
        wanted = set(args.only.split(","))
        tracks = [t for t in tracks if Path(t).stem in wanted]
    rk: ResidualMPCConfig = replace(RKMPC_CONFIG, **json.loads(args.rkmpc))
    studies = [
        CompareConfig(t, controllers=controllers, seed=args.seed, kmpc_model=kmpc, rkmpc=rk) for t in tracks
    ]
    rows = []
    # Spawned workers: forking after PyTorch has started its threads can deadlock.
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=spawn) as pool:
        for res in pool.map(_job, studies):
            rows.append(res)
            base = res["controllers"].get("lmpc", {})
            line = [res["track"]]
            for name, m in res["controllers"].items():
                ch = "/".join(_change(m[k], base.get(k)) for k, _ in KEYS)
                line.append(
                    f"{name}:{'ok' if m['completed'] else 'FAIL'} {m['lateral_error_mean_m'] or 0:.4f} {ch}"
                )
            print("  ".join(line), flush=True)
    write_json_atomic(args.out / "learning.json", {"tracks": rows})
    header = [
        "track",
        "controller",
        "done",
        "lat (m)",
        "head (rad)",
        "rate (rad/s)",
        "vs LMPC lat/head/rate",
        "t mean/p99/max (ms)",
    ]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    summary: dict[str, list[list[float]]] = {}
    for res in rows:
        base = res["controllers"].get("lmpc", {})
        for name, m in res["controllers"].items():
            ch = " / ".join(_change(m[k], base.get(k)) for k, _ in KEYS)
            t = f"{m['solve_ms_mean']:.2f} / {m['solve_ms_p99']:.2f} / {m['solve_ms_max']:.2f}"
            lat, head, rate = (m[k] for k, _ in KEYS)
            done = "yes" if m["completed"] else "NO " + format(m["progress"], ".0%")
            lines.append(
                f"| {res['track']} | {name} | {done} | {lat:.4f} | {head:.4f} | {rate:.4f} | {ch} | {t} |"
            )
            if base and m["completed"]:
                summary.setdefault(name, []).append([100 * (m[k] - base[k]) / base[k] for k, _ in KEYS])
    lines.append("")
    lines.append(
        "| controller | tracks completed | mean change lat / head / rate | worst track lat / head / rate |"
    )
    lines.append("|---|---|---|---|")
    for res_name in controllers:
        done = sum(r["controllers"].get(res_name, {}).get("completed", False) for r in rows)
        ch = np.array(summary.get(res_name, [[np.nan] * 3]))
        lines.append(
            f"| {res_name} | {done}/{len(rows)} | "
            + " / ".join(f"{v:+.1f}%" for v in ch.mean(axis=0))
            + " | "
            + " / ".join(f"{v:+.1f}%" for v in ch.max(axis=0))
            + " |"
        )
    (args.out / "learning.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines[-(len(controllers) + 2) :]))


if __name__ == "__main__":
    main()
