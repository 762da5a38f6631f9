"""Tracking metrics of one run, as in the paper's Table I."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from rkmpc.sim.closed_loop import SimResult
from rkmpc.sim.log import StepLog

#: Keys of :func:`lap_metrics`, in table order.
METRIC_KEYS = (
    "completed",
    "progress",
    "lap_time_s",
    "lateral_error_mean_m",
    "lateral_error_max_m",
    "heading_error_mean_rad",
    "steer_rate_mean_rad_s",
    "command_rate_mean_rad_s",
    "solve_ms_mean",
    "solve_ms_p99",
    "solve_ms_max",
    "fallback_count",
    "steps",
    "lateral_accel_max_m_s2",
)


#: Keys added after the first result files were written; older files read them as None.
_ADDED_KEYS = frozenset({"command_rate_mean_rad_s"})


@dataclass(frozen=True)
class LapMetrics(Mapping[str, Any]):
    """The metrics of one run (see :func:`lap_metrics`), typed; also a read-only mapping by key.

    The fields are :data:`METRIC_KEYS`, in order; ``None`` where a metric is undefined (a lap
    time of a lap not completed, errors of a run without steps). Beyond them (not a table
    column, not in the mapping), ``status_counts``: the controller's steps by status
    (:data:`rkmpc.control.base.STATUSES`), None for files written before it was counted.
    """

    completed: bool
    progress: float
    lap_time_s: float | None
    lateral_error_mean_m: float | None
    lateral_error_max_m: float | None
    heading_error_mean_rad: float | None
    steer_rate_mean_rad_s: float | None
    command_rate_mean_rad_s: float | None
    solve_ms_mean: float | None
    solve_ms_p99: float | None
    solve_ms_max: float | None
    fallback_count: int
    steps: int
    lateral_accel_max_m_s2: float | None
    status_counts: dict[str, int] | None = None

    def __getitem__(self, key: str) -> Any:
        if key not in METRIC_KEYS:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(METRIC_KEYS)

    def __len__(self) -> int:
        return len(METRIC_KEYS)

    def to_json(self) -> dict[str, Any]:
        """The metrics as a plain dict, in :data:`METRIC_KEYS` order, then ``status_counts``."""
        return {**{key: getattr(self, key) for key in METRIC_KEYS}, "status_counts": self.status_counts}

    @classmethod
    def not_driven(cls) -> LapMetrics:
        """The metrics of a run that never started: not completed, no steps, every error None."""
        return cls(
            completed=False,
            progress=0.0,
            lap_time_s=None,
            lateral_error_mean_m=None,
            lateral_error_max_m=None,
            heading_error_mean_rad=None,
            steer_rate_mean_rad_s=None,
            command_rate_mean_rad_s=None,
            solve_ms_mean=None,
            solve_ms_p99=None,
            solve_ms_max=None,
            fallback_count=0,
            steps=0,
            lateral_accel_max_m_s2=None,
        )

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> LapMetrics:
        """Metrics read back from :meth:`to_json` output (extra keys are ignored)."""
        # Files written before the commanded-steering rate was measured lack only that key.
        values: dict[str, Any] = {
            key: data[key] if key in data or key not in _ADDED_KEYS else None for key in METRIC_KEYS
        }
        counts = data["status_counts"] if "status_counts" in data else None
        return cls(
            **values, status_counts=None if counts is None else {str(k): int(v) for k, v in counts.items()}
        )


def lap_metrics(result: SimResult, laps: int = 1) -> LapMetrics:
    """Metrics of a run: completion over the laps asked for, everything per step over the first lap.

    The errors, the wheel-angle rate, the step times and the peak lateral
    acceleration are taken over the steps of the first lap (or as far as the
    run got); ``fallback_count`` and ``steps`` count the whole run.

    Parameters
    ----------
    result : SimResult
        The run.
    laps : int
        Laps the run was asked to drive (progress is a fraction of these).

    Returns
    -------
    LapMetrics
        ``completed`` (bool), ``progress`` (fraction of the requested laps,
        0-1), ``lap_time_s`` (first lap, s; None if not completed),
        ``lateral_error_mean_m`` and ``lateral_error_max_m`` (absolute offset
        from the reference path, m), ``heading_error_mean_rad`` (mean absolute
        heading error, rad), ``steer_rate_mean_rad_s`` (mean absolute rate of
        the actual front wheel angle, rad/s), ``command_rate_mean_rad_s``
        (mean absolute rate of the commanded wheel angle, rad/s: on a servo
        that limit-cycles, the actual rate says nothing about the
        controller), ``solve_ms_mean``,
        ``solve_ms_p99``, ``solve_ms_max`` (controller step time, ms),
        ``fallback_count``, ``steps``, ``lateral_accel_max_m_s2`` (largest
        ``|speed * yaw rate|`` of the true state, m/s^2; None when the plant
        does not report both) and ``status_counts`` (the controller's steps by
        status over the whole run, :data:`rkmpc.control.base.STATUSES`; None in
        files written before it was counted).
    """
    log = result.log
    t = log["t"]
    progress_m = log["progress"]
    n = len(t)
    first_lap = progress_m <= result.lap_length
    lat = np.abs(log["lateral_error"][first_lap])
    head = np.abs(log["heading_error"][first_lap])
    wheel = log["wheel_angle"][first_lap]
    dt = float(np.median(np.diff(t))) if n > 1 else math.nan
    steer_rate = np.abs(np.diff(wheel)) / dt if len(wheel) > 1 else np.array([math.nan])
    commanded = log["cmd_steer"][first_lap]
    command_rate = np.abs(np.diff(commanded)) / dt if len(commanded) > 1 else np.array([math.nan])
    solve_ms = 1e3 * log["solve_time_s"][first_lap]
    solve_ms = solve_ms[np.isfinite(solve_ms)]
    return LapMetrics(
        completed=bool(result.completed),
        progress=float(min(result.progress / laps, 1.0)),
        lap_time_s=float(result.lap_times[0]) if result.lap_times else None,
        lateral_error_mean_m=_mean(lat),
        lateral_error_max_m=float(lat.max()) if lat.size else None,
        heading_error_mean_rad=_mean(head),
        steer_rate_mean_rad_s=_mean(steer_rate),
        command_rate_mean_rad_s=_mean(command_rate),
        solve_ms_mean=_mean(solve_ms),
        solve_ms_p99=float(np.percentile(solve_ms, 99)) if solve_ms.size else None,
        solve_ms_max=float(solve_ms.max()) if solve_ms.size else None,
        fallback_count=int(result.fallback_count),
        steps=int(n),
        lateral_accel_max_m_s2=_peak_lateral_accel(log, first_lap),
        status_counts=dict(sorted(result.status_counts.items())),
    )


def _peak_lateral_accel(log: StepLog, rows: np.ndarray) -> float | None:
    if "state_v" not in log.columns or "state_yaw_rate" not in log.columns:
        return None
    acc = np.abs(log["state_v"][rows] * log["state_yaw_rate"][rows])
    acc = acc[np.isfinite(acc)]
    return float(acc.max()) if acc.size else None


def _mean(values: np.ndarray) -> float | None:
    values = values[np.isfinite(values)]
    return float(values.mean()) if values.size else None
