"""Benchmark the state estimator: what it adds to a control step.

Run: ``python benchmarks/bench_estimator.py --out runs/bench/estimator.json``. One LMPC lap of the
track drives the simulated F1TENTH car through a real car's sensors (pose at 20-40 Hz, 30-60 ms
late, with jumps; a mis-scaled wheel speed; a biased gyro; no wheel angle: the test helper
``tests/estimation/sensor_faults.py``), with the controller wrapped in
:class:`rkmpc.control.estimated.EstimatedController`. Reported, in microseconds:

* ``update``: :meth:`StateEstimator.update` alone, timed call by call over the lap's recorded raw
  observations and commands, ``--repeat`` passes (``update_cpu``: the same in the thread's CPU
  time, which other processes on a busy machine do not inflate);
* ``added_to_step``: the wrapper's step time less the inner LMPC's, step by step in the loop (the
  estimator plus the wrapper's own bookkeeping);
* ``smoother_per_sample``: :func:`smooth_sequence` over the lap, divided by its samples.

Median, p99 and max; one thread. The issue's budget: at most 100 us median added to a step.
"""

from __future__ import annotations

import os

# One thread per process: small dense algebra is slower with thread pools.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import sys
from pathlib import Path
from time import perf_counter, perf_counter_ns, thread_time_ns

import numpy as np

from rkmpc.control.estimated import EstimatedController
from rkmpc.control.registry import make_controller
from rkmpc.core.io import write_json_atomic
from rkmpc.core.observation import Command
from rkmpc.core.versions import versions
from rkmpc.estimation import EstimatorConfig, StateEstimator
from rkmpc.estimation.smoother import smooth_sequence
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.scenario import load_scenario
from rkmpc.vehicle.registry import make_plant

ROOT = Path(__file__).resolve().parents[1]
# The sensors of a real car, as the tests inject them (one definition of them).
sys.path.insert(0, str(ROOT / "tests" / "estimation"))
from sensor_faults import Faults, RealSensors

SHARED_MONZA = ROOT.parent / "shared" / "tracks" / "centerlines" / "Monza.csv"


def stats(us: np.ndarray) -> dict[str, float]:
    """Median, p99 and max (us) and the count."""
    return {
        "samples": int(us.size),
        "median_us": float(np.median(us)),
        "p99_us": float(np.percentile(us, 99)),
        "max_us": float(us.max()),
    }


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--track", default=str(SHARED_MONZA) if SHARED_MONZA.exists() else "builtin")
    parser.add_argument("--repeat", type=int, default=5, help="passes of update() over the lap")
    parser.add_argument("--out", type=Path, default=Path("runs/bench/estimator.json"))
    args = parser.parse_args()
    scenario = load_scenario(args.track)
    config = EstimatorConfig(control_period=scenario.dt)
    plant = RealSensors(make_plant("f1tenth"), Faults(), seed=0)
    controller = EstimatedController(
        make_controller("lmpc", scenario.reference, scenario.vehicle),
        StateEstimator(scenario.vehicle, config),
    )
    added: list[float] = []

    def on_step(t: float, progress: float) -> None:
        added.append(controller.info.solve_time_s - controller.inner.info.solve_time_s)

    result = simulate(
        plant, controller, scenario.track, scenario.reference, SimConfig(dt=scenario.dt), on_step=on_step
    )
    n = len(added)
    raw = plant.delivered[:n]
    commands = np.column_stack([result.log["cmd_speed"], result.log["cmd_steer"]])[:n]
    sent = [None] + [Command(float(v), float(d)) for v, d in commands[:-1]]

    estimator = StateEstimator(scenario.vehicle, config)
    wall: list[int] = []
    cpu: list[int] = []
    for _ in range(args.repeat):
        estimator.reset()
        for observation, command in zip(raw, sent, strict=True):
            c0, t0 = thread_time_ns(), perf_counter_ns()
            estimator.update(observation, command)
            wall.append(perf_counter_ns() - t0)
            cpu.append(thread_time_ns() - c0)
    t0 = perf_counter()
    smooth_sequence(
        np.array([o.time for o in raw]),
        np.array([o.as_array() for o in raw]),
        commands,
        scenario.vehicle,
        config=config,
        pose_times=np.array([o.pose_time for o in raw]),
    )
    smoother_us = 1e6 * (perf_counter() - t0) / n
    report = {
        "track": scenario.track.name,
        "outcome": result.outcome,
        "steps": n,
        "update": stats(1e-3 * np.array(wall, dtype=float)),
        "update_cpu": stats(1e-3 * np.array(cpu, dtype=float)),
        "load_average_1min": os.getloadavg()[0],
        "added_to_step": stats(1e6 * np.array(added)),
        "smoother_per_sample_us": smoother_us,
        "diagnostics": estimator.diagnostics().as_dict(prefix=""),
        "versions": versions(),
    }
    print(f"track {scenario.track.name}: {n} steps, LMPC through a real car's sensors, {result.outcome}")
    print(f"{'':22s} {'median':>8s} {'p99':>8s} {'max':>8s}  (us)")
    for label in ("update", "update_cpu", "added_to_step"):
        s = report[label]
        print(f"{label:22s} {s['median_us']:8.1f} {s['p99_us']:8.1f} {s['max_us']:8.1f}")  # type: ignore[index]
    print(f"smoother per sample    {smoother_us:8.1f}")
    write_json_atomic(args.out, report)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
