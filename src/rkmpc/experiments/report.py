"""What a comparison leaves in its output folder: results, tables, logs' plots.

``results.json`` (or ``metrics.json`` for a single controller) is
:meth:`rkmpc.experiments.results.TrackResult.to_json`; ``table.md`` the
comparison table (and the fault table); ``plot.png`` the paths and errors,
``solve_times.png`` the step times, ``plot_fault.png`` the runs with the fault.
Every file is written whole or not at all.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from rkmpc.analysis.plots import plot_runs, plot_solve_times, save_figure
from rkmpc.analysis.tables import fault_table, markdown_table
from rkmpc.core.io import write_json_atomic, write_text_atomic
from rkmpc.experiments.results import NOT_LEARNED, TrackResult
from rkmpc.sim.log import StepLog
from rkmpc.track.track import Track

__all__ = ["lateral_limit_of", "title_of", "write_comparison", "write_single_run"]


def title_of(result: TrackResult) -> str:
    """``"<track> (scale <s>, <vehicle>)"``, the title of a comparison's figures and tables."""
    scenario = result.config["scenario"]
    return f"{scenario['track']} (scale {scenario['scale']:g}, {scenario['vehicle']})"


def lateral_limit_of(result: TrackResult) -> float:
    """The pace's lateral-acceleration limit of a comparison (m/s^2): what its tables flag peaks by."""
    return float(result.config["scenario"]["speed_limits"]["lateral_accel"])


def _nominal(logs: Mapping[str, StepLog]) -> dict[str, StepLog]:
    return {label: log for label, log in logs.items() if "+" not in label}


def write_comparison(out: Path, result: TrackResult, logs: Mapping[str, StepLog], track: Track) -> None:
    """Write ``results.json``, ``table.md``, ``plot.png``, ``solve_times.png`` (and ``plot_fault.png``)."""
    write_json_atomic(out / "results.json", result.to_json())
    text = markdown_table(result.metrics(), lateral_limit=lateral_limit_of(result))
    unlearned = [(n, run.failure) for n, run in result.controllers.items() if run.outcome == NOT_LEARNED]
    if unlearned:
        text += "\n" + "".join(f"- `{name}` did not drive, not learned: {why}\n" for name, why in unlearned)
    if result.fault is not None:
        nominal = result.metrics()
        faulted = {name: run.metrics for name, run in result.fault.runs.items()}
        text += "\n" + fault_table(nominal, faulted, result.fault.effects, result.fault.fault)
    write_text_atomic(out / "table.md", text)
    title = title_of(result)
    save_figure(plot_runs(_nominal(logs), track, title=title), out / "plot.png")
    period = result.config["scenario"]["dt"]
    save_figure(plot_solve_times(_nominal(logs), period_s=period, title=title), out / "solve_times.png")
    _write_fault_plot(out, result, logs, track)


def write_single_run(out: Path, result: TrackResult, logs: Mapping[str, StepLog], track: Track) -> None:
    """``metrics.json`` and ``plot.png`` (and ``plot_fault.png``) of a one-controller run in ``out``."""
    name = next(iter(result.controllers))
    payload = {
        **result.controllers[name].to_json(),
        "training": result.training.to_json(),
        "config": result.config,
    }
    write_json_atomic(out / "metrics.json", payload)
    save_figure(plot_runs(_nominal(logs), track, title=title_of(result)), out / "plot.png")
    _write_fault_plot(out, result, logs, track)


def _write_fault_plot(out: Path, result: TrackResult, logs: Mapping[str, StepLog], track: Track) -> None:
    if result.fault is None:
        return
    faulted = {label: log for label, log in logs.items() if "+" in label}
    title = f"{title_of(result)}, fault: {result.fault.fault}"
    save_figure(plot_runs(faulted, track, title=title), out / "plot_fault.png")
