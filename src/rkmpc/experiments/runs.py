"""One run, measured: drive a controller (:func:`rkmpc.sim.run.drive`) and take its lap metrics."""

from __future__ import annotations

from collections.abc import Callable

from rkmpc.analysis.metrics import LapMetrics, lap_metrics
from rkmpc.sim.closed_loop import SimResult
from rkmpc.sim.run import RunSpec, drive
from rkmpc.sim.scenario import Scenario

__all__ = ["run_controller"]


def run_controller(
    scenario: Scenario,
    spec: RunSpec,
    *,
    model: object = None,
    allow_mismatch: bool = False,
    on_step: Callable[[float, float], None] | None = None,
) -> tuple[SimResult, LapMetrics]:
    """Drive one controller in the scenario and measure it.

    Returns
    -------
    result : SimResult
        Log and outcome.
    metrics : LapMetrics
        :func:`rkmpc.analysis.metrics.lap_metrics` of the run over the spec's laps.
    """
    result = drive(scenario, spec, model=model, allow_mismatch=allow_mismatch, on_step=on_step)
    return result, lap_metrics(result, laps=spec.laps)
