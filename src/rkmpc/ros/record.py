"""What ``rkmpc node`` saw and sent, as files: one row per command, and a summary.

``node_log.csv`` has one row per :class:`~rkmpc.ros.driver.Decision` (the command, its state,
the odometry it was made from, its errors and the controller's step time); ``node_summary.json``
counts the commands by state and gives the odometry-to-command latency (from an odometry's
arrival to the first command made from it: its age when the decision began plus the controller's
step; median, 99th percentile, largest) and the step times.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.core.io import write_json_atomic, write_text_atomic
from rkmpc.ros.driver import Decision

__all__ = ["LOG_COLUMNS", "summarise", "write_record"]

#: Columns of ``node_log.csv`` (SI units; ``obs_*`` are the odometry as received).
LOG_COLUMNS = (
    "time",
    "wall",
    "state",
    "speed",
    "steer",
    "odometry_age_s",
    "lateral_error_m",
    "heading_error_rad",
    "solve_time_s",
    "status",
    "fresh",
    "obs_time",
    "obs_x",
    "obs_y",
    "obs_yaw",
    "obs_speed",
    "obs_yaw_rate",
    "obs_steer_angle",
)


def _row(d: Decision) -> list[Any]:
    o = d.observation
    seen = (math.nan,) * 7 if o is None else (o.time, o.x, o.y, o.yaw, o.speed, o.yaw_rate, o.steer_angle)
    return [
        d.time,
        d.wall,
        d.state,
        d.command.speed,
        d.command.steer,
        d.odometry_age_s,
        d.lateral_error_m,
        d.heading_error_rad,
        d.solve_time_s,
        d.status,
        int(d.fresh),
        *seen,
    ]


def _stats_ms(values: Iterable[float]) -> dict[str, float | None]:
    array = 1e3 * np.asarray([v for v in values if math.isfinite(v)], dtype=float)
    if not array.size:
        return {"median": None, "p99": None, "max": None}
    return {
        "median": float(np.median(array)),
        "p99": float(np.percentile(array, 99)),
        "max": float(array.max()),
    }


def summarise(decisions: Iterable[Decision], extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Counts by state, odometry-to-command latency and step times (ms) of the decisions."""
    rows = list(decisions)
    running = [d for d in rows if d.state == "running"]
    fresh = [d for d in running if d.fresh]
    counts: dict[str, int] = {}
    for d in rows:
        counts[d.state] = counts.get(d.state, 0) + 1
    return {
        "commands": len(rows),
        "by_state": counts,
        "odometry_to_command_ms": _stats_ms(
            d.odometry_age_s + (d.solve_time_s if math.isfinite(d.solve_time_s) else 0.0) for d in fresh
        ),
        "solve_time_ms": _stats_ms(d.solve_time_s for d in running),
        **(extra or {}),
    }


def write_record(folder: Path, decisions: Iterable[Decision], extra: Mapping[str, Any] | None = None) -> None:
    """Write ``node_log.csv`` and ``node_summary.json`` into ``folder`` (created when missing)."""
    rows = list(decisions)
    folder.mkdir(parents=True, exist_ok=True)
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(LOG_COLUMNS)
    writer.writerows(_row(d) for d in rows)
    write_text_atomic(folder / "node_log.csv", text.getvalue())
    write_json_atomic(folder / "node_summary.json", summarise(rows, extra))
