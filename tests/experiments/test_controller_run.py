"""A controller's run keeps its own counts (the steps its guards and limits acted on) through JSON."""

from __future__ import annotations

import json

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.experiments.results import ControllerRun


def test_a_run_keeps_its_diagnostics_through_json():
    run = ControllerRun(
        metrics=LapMetrics.not_driven(),
        outcome="completed",
        diagnostics={"slip_drift_faded": 3.0, "lateral_guard_steps": 14.0},
    )
    data = json.loads(json.dumps(run.to_json()))
    assert data["diagnostics"] == {"slip_drift_faded": 3.0, "lateral_guard_steps": 14.0}
    assert ControllerRun.from_json(data) == run


def test_a_run_written_before_runs_kept_diagnostics_reads_back_with_none():
    data = ControllerRun(metrics=LapMetrics.not_driven(), outcome="off_track").to_json()
    del data["diagnostics"]
    back = ControllerRun.from_json(data)
    assert back.diagnostics == {} and back.outcome == "off_track"
