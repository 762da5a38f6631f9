"""Where the time of one RKMPC step goes.

Run: ``make bench-breakdown`` (or ``python benchmarks/bench_breakdown.py --out FILE``).
The default ``rkmpc`` drives one lap of the track in closed loop (model learned
as ``rkmpc compare`` does, from the cache when there); the stages of each step
are timed by wrapping the methods that do them on this one controller instance,
so the code that runs is the controller's own. Per stage: median and mean in
microseconds per step; "other" is the step time not spent in any timed stage
(Python glue, guards, the command). Writes JSON.
"""

from __future__ import annotations

import os

# One thread per process: small dense algebra is slower with thread pools.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import copy
import functools
from collections.abc import Callable
from pathlib import Path
from time import perf_counter
from typing import Any

import numpy as np

from rkmpc.control.registry import make_controller
from rkmpc.core.io import write_json_atomic
from rkmpc.core.versions import versions
from rkmpc.experiments.compare import CompareConfig
from rkmpc.experiments.models import learn_models
from rkmpc.sim.build import check_model
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.run import RunSpec, build_plant
from rkmpc.sim.scenario import load_scenario

SHARED_MONZA = Path(__file__).resolve().parents[1].parent / "shared" / "tracks" / "centerlines" / "Monza.csv"


class StageTimer:
    """Accumulates the wall-clock time of wrapped calls per stage, reset at every control step."""

    def __init__(self) -> None:
        self.current: dict[str, float] = {}
        self.steps: list[dict[str, float]] = []

    def wrap(self, owner: Any, method: str, stage: str) -> None:
        """Replace ``owner.method`` (on this instance only) by a timed call added to ``stage``."""
        inner: Callable[..., Any] = getattr(owner, method)

        @functools.wraps(inner)
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                self.current[stage] = self.current.get(stage, 0.0) + perf_counter() - t0

        setattr(owner, method, timed)

    def close_step(self, total: float) -> None:
        """Store the stages of the step that just ended; ``total`` is its whole time (s)."""
        stages = dict(self.current)
        stages["other"] = total - sum(stages.values())
        stages["total"] = total
        self.steps.append(stages)
        self.current = {}


def instrument(controller: Any, timer: StageTimer) -> None:
    """Time the stages of a ``ResidualKoopmanMPC`` step."""
    lmpc = controller.lmpc
    timer.wrap(lmpc.reference, "project", "lmpc: projection")
    timer.wrap(lmpc.reference, "horizon", "lmpc: reference horizon")
    timer.wrap(lmpc.problem, "prediction_matrices", "lmpc: linearisation + condensing")
    timer.wrap(lmpc.problem, "qp_numbers", "lmpc: QP numbers (Hessian, gradient, bounds)")
    timer.wrap(lmpc._qp, "update", "lmpc: QP update (Cholesky, R^-1, DAQP rows)")
    timer.wrap(lmpc._qp, "solve", "lmpc: DAQP solve")
    timer.wrap(controller.model, "lift", "residual: network lift")
    timer.wrap(controller, "_residual_qp", "residual: QP numbers")
    timer.wrap(controller._qp, "update", "residual: QP update (Cholesky, R^-1, DAQP rows)")
    timer.wrap(controller._qp, "solve", "residual: DAQP solve")


def main() -> None:
    """Entry point."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--track", default=str(SHARED_MONZA) if SHARED_MONZA.exists() else "builtin")
    parser.add_argument("--out", type=Path, default=Path("runs/bench/breakdown.json"))
    args = parser.parse_args()
    scenario = load_scenario(args.track)
    study = CompareConfig(
        track=scenario.track.source or scenario.track.name, car=scenario.car, controllers=("rkmpc",)
    )
    models, _ = learn_models(scenario, study.plan())
    model = models["rkmpc"]
    check_model(model, scenario, source="the rkmpc model")
    # The controller gets its own reference object: the simulator's projections are not timed.
    reference = copy.copy(scenario.reference)
    settings = scenario.car.controllers.with_period(scenario.dt)
    controller = make_controller("rkmpc", reference, scenario.vehicle, settings=settings, model=model)
    timer = StageTimer()
    instrument(controller, timer)

    def on_step(_time: float, _progress: float) -> None:
        timer.close_step(controller.info.solve_time_s)

    plant = build_plant(scenario, RunSpec(controller="rkmpc"))
    config = SimConfig(dt=scenario.dt)
    result = simulate(plant, controller, scenario.track, scenario.reference, config, on_step=on_step)
    steps = timer.steps[1:]  # the first step sets the solvers up
    names = [name for name in steps[0] if name not in ("other", "total")] + ["other", "total"]
    report: dict[str, Any] = {
        "track": scenario.track.name,
        "outcome": result.outcome,
        "steps": len(steps),
        "horizon": controller.horizon,
        "versions": versions(),
        "stages_us": {},
    }
    print(f"{scenario.track.name}: {len(steps)} rkmpc steps, N = {controller.horizon}, {result.outcome}")
    print(f"{'stage':50s} {'median':>8s} {'mean':>8s}  (us per step)")
    for name in names:
        values = 1e6 * np.array([s.get(name, 0.0) for s in steps])
        stats = {"median_us": float(np.median(values)), "mean_us": float(values.mean())}
        report["stages_us"][name] = stats
        print(f"{name:50s} {stats['median_us']:8.1f} {stats['mean_us']:8.1f}")
    write_json_atomic(args.out, report)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
