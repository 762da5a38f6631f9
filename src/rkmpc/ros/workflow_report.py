"""The report of ``rkmpc car-loop``: the paper's Table II of the run, the latencies, the delay runs.

Built from what the processes wrote: the simulated car's ``summary.json`` (the lap's metrics,
:func:`rkmpc.analysis.metrics.lap_metrics`, and in lock-step the round trip it waited for each
command) and the node's ``node_summary.json`` (the controller's step time, the age of each
odometry when its command went out). Written as ``table2.json`` and ``table2.md``, each whole or
not at all.

Table II's columns: mean lateral error (m), mean heading error (rad), mean rate of the actual
front wheel angle (rad/s), the controller's step time in the node (median and 99th percentile,
ms), and the latency odometry -> command (median, 99th percentile, ms). The latency is what
the clock lets one measure: in lock-step the round trip at the car, from publishing an odometry
to receiving the command that answers it (wall clock, ``sim-node``); in real time from an
odometry's arrival at the node to the first command made from it (the wait for the node's 20 Hz
timer and the controller's step).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from rkmpc.analysis.tables import fmt, markdown
from rkmpc.core.io import write_json_atomic, write_text_atomic

__all__ = ["TABLE_KEYS", "build_report", "markdown_report", "table_row", "write_report"]

#: Keys of a row of Table II, in column order (SI units; times in ms).
TABLE_KEYS = (
    "completed",
    "lateral_error_mean_m",
    "heading_error_mean_rad",
    "steer_rate_mean_rad_s",
    "step_ms_median",
    "step_ms_p99",
    "latency_ms_median",
    "latency_ms_p99",
)
_HEADER = (
    "controller",
    "completed",
    "lateral error (m)",
    "heading error (rad)",
    "wheel-angle rate (rad/s)",
    "step median (ms)",
    "step p99 (ms)",
    "latency median (ms)",
    "latency p99 (ms)",
)
_LATENCY = {
    "lockstep": "round trip at the car: odometry published -> its command received (sim-node, wall clock)",
    "realtime": "odometry's arrival at the node -> the first command made from it sent (node, wall clock)",
}


def table_row(run: Mapping[str, Any], clock: str) -> dict[str, Any]:
    """One row of Table II (and the run's other figures) from a run's two summaries."""
    sim, node = run["sim"], run["node"]
    metrics = sim["metrics"]
    if clock == "lockstep":
        latency = {"median": sim["round_trip_ms_median"], "p99": sim["round_trip_ms_p99"]}
    else:
        latency = node["odometry_to_command_ms"]
    return {
        "completed": bool(metrics["completed"]),
        "lateral_error_mean_m": metrics["lateral_error_mean_m"],
        "heading_error_mean_rad": metrics["heading_error_mean_rad"],
        "steer_rate_mean_rad_s": metrics["steer_rate_mean_rad_s"],
        "step_ms_median": node["solve_time_ms"]["median"],
        "step_ms_p99": node["solve_time_ms"]["p99"],
        "latency_ms_median": latency["median"],
        "latency_ms_p99": latency["p99"],
        "outcome": sim["outcome"],
        "progress": metrics["progress"],
        "lap_time_s": metrics["lap_time_s"],
        "lateral_error_max_m": metrics["lateral_error_max_m"],
        "steps": metrics["steps"],
        "fallbacks": node["fallbacks"],
        "commands_by_state": node["by_state"],
        "odometry_to_command_ms": node["odometry_to_command_ms"],
        "round_trip_ms": {"median": sim["round_trip_ms_median"], "p99": sim["round_trip_ms_p99"]},
        "actuation_delay_s": run["actuation_delay"],
        "compensate": run["compensate"],
    }


def _change(rows: Mapping[str, Mapping[str, Any]], key: str, name: str, baseline: str) -> float | None:
    if name not in rows or baseline not in rows:
        return None
    value, base = rows[name][key], rows[baseline][key]
    return None if value is None or not base else 100.0 * (value - base) / base


def build_report(
    *,
    config: Mapping[str, Any],
    record: Mapping[str, Any],
    imported: str,
    models: Mapping[str, Mapping[str, str]],
    table: Mapping[str, Mapping[str, Any]],
    delayed: Mapping[str, Mapping[str, Any]],
    commands: Sequence[str],
) -> dict[str, Any]:
    """The whole report (JSON-ready): settings, data, models, Table II, the delay runs, the commands."""
    clock = str(config["clock"])
    rows = {name: table_row(run, clock) for name, run in table.items()}
    comparison = None
    if "rkmpc" in rows and "lmpc" in rows:
        lateral = _change(rows, "lateral_error_mean_m", "rkmpc", "lmpc")
        heading = _change(rows, "heading_error_mean_rad", "rkmpc", "lmpc")
        comparison = {
            "lateral_change_pct": lateral,
            "heading_change_pct": heading,
            "rkmpc_beats_lmpc": bool(
                rows["rkmpc"]["completed"]
                and lateral is not None
                and heading is not None
                and lateral < 0
                and heading < 0
            ),
        }
    return {
        "config": dict(config),
        "latency_measure": _LATENCY[clock],
        "record": {"sim": record["sim"], "node": record["node"], "import": imported},
        "models": {kind: dict(info) for kind, info in models.items()},
        "table2": rows,
        "rkmpc_vs_lmpc": comparison,
        "delay": {name: table_row(run, clock) for name, run in delayed.items()},
        "commands": list(commands),
    }


def _cells(name: str, row: Mapping[str, Any]) -> list[str]:
    return [
        name,
        "yes" if row["completed"] else f"no ({row['outcome']}, {100 * row['progress']:.0f} %)",
        fmt(row["lateral_error_mean_m"]),
        fmt(row["heading_error_mean_rad"]),
        fmt(row["steer_rate_mean_rad_s"], ".3f"),
        fmt(row["step_ms_median"], ".2f"),
        fmt(row["step_ms_p99"], ".2f"),
        fmt(row["latency_ms_median"], ".2f"),
        fmt(row["latency_ms_p99"], ".2f"),
    ]


def markdown_report(report: Mapping[str, Any]) -> str:
    """``table2.md``: Table II, RKMPC against the LMPC, the delay runs, the data, the commands."""
    config = report["config"]
    lines = [
        f"# Table II over ROS 2: {config['track']}, {config['clock']} clock",
        "",
        markdown(_HEADER, [_cells(name, row) for name, row in report["table2"].items()]),
        "",
        f"Latency: {report['latency_measure']}. Step: the controller's step in the node.",
    ]
    comparison = report["rkmpc_vs_lmpc"]
    if comparison is not None:
        verdict = "beats" if comparison["rkmpc_beats_lmpc"] else "does not beat"
        lines += [
            "",
            f"RKMPC {verdict} the LMPC on lateral and heading error: lateral "
            f"{fmt(comparison['lateral_change_pct'], '+.1f')} %, heading "
            f"{fmt(comparison['heading_change_pct'], '+.1f')} %.",
        ]
    if report["delay"]:
        lines += [
            "",
            f"## {1e3 * config['delay']:g} ms of added actuation delay (+comp: with latency compensation)",
            "",
            markdown(_HEADER, [_cells(name, row) for name, row in report["delay"].items()]),
        ]
    lines += ["", "## Data and models", "", f"- recorded and imported: {report['record']['import']}"]
    for kind, info in report["models"].items():
        text = info["report"].replace("\n", "; ")
        lines.append(f"- {kind}: {text}")
    lines += ["", "## Commands", "", "```", *report["commands"], "```", ""]
    return "\n".join(lines)


def write_report(folder: Path, report: Mapping[str, Any]) -> None:
    """``table2.json`` and ``table2.md`` in ``folder``, each written atomically."""
    write_json_atomic(folder / "table2.json", report)
    write_text_atomic(folder / "table2.md", markdown_report(report))
