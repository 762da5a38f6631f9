"""Statistics over runs: summaries of values and changes against a baseline.

:class:`Stats` summarises values: ``n`` values, their ``mean``, sample
standard deviation ``std`` (``ddof=1``; None for fewer than two values),
``min`` and ``max``; None everywhere for no values. Non-finite values and None
are left out. :func:`change_pct` is the one relative change of the package.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rkmpc.analysis.metrics import METRIC_KEYS

__all__ = [
    "CHANGE_METRICS",
    "SUMMARY_METRICS",
    "ControllerSummary",
    "RunGroup",
    "RunRow",
    "Stats",
    "change_pct",
    "stats",
    "summarise_runs",
]

#: Lap metrics summarised over runs: the numeric ones of :data:`~rkmpc.analysis.metrics.METRIC_KEYS`.
SUMMARY_METRICS = tuple(k for k in METRIC_KEYS if k not in ("completed", "steps", "lateral_accel_max_m_s2"))

#: Metrics whose change against a baseline is reported (not ``progress``: both laps are complete
#: where a change is computed).
CHANGE_METRICS = tuple(m for m in SUMMARY_METRICS if m != "progress")


@dataclass(frozen=True)
class Stats:
    """Summary of a set of values (see the module docstring)."""

    n: int
    mean: float | None
    std: float | None
    min: float | None
    max: float | None

    def to_json(self) -> dict[str, Any]:
        """``{"n", "mean", "std", "min", "max"}``."""
        return {"n": self.n, "mean": self.mean, "std": self.std, "min": self.min, "max": self.max}


def stats(values: Iterable[float | None]) -> Stats:
    """:class:`Stats` of the finite values among ``values`` (None and NaN are left out)."""
    arr = np.array(
        [float(v) for v in values if v is not None and math.isfinite(float(v))],
        dtype=float,
    )
    n = int(arr.size)
    if n == 0:
        return Stats(n=0, mean=None, std=None, min=None, max=None)
    return Stats(
        n=n,
        mean=float(arr.mean()),
        std=float(arr.std(ddof=1)) if n > 1 else None,
        min=float(arr.min()),
        max=float(arr.max()),
    )


def change_pct(value: float | None, base: float | None) -> float | None:
    """``100 * (value - base) / base``; None where either is missing or not finite, or ``base`` is 0."""
    if value is None or base is None:
        return None
    value, base = float(value), float(base)
    if not (math.isfinite(value) and math.isfinite(base)) or base == 0.0:
        return None
    return 100.0 * (value - base) / base


@dataclass(frozen=True)
class RunGroup:
    """The runs of several controllers under the same conditions (one track and seed).

    Parameters
    ----------
    track : str
        Track name.
    seed : int
        Seed.
    ok : bool
        False when the group's job failed (no run).
    error : str or None
        The failure message.
    metrics : mapping of str to mapping
        Lap metrics by controller (a :class:`~rkmpc.analysis.metrics.LapMetrics` or its JSON).
    """

    track: str
    seed: int
    ok: bool
    error: str | None
    metrics: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class RunRow:
    """One controller in one :class:`RunGroup`: ``status`` is ``"ran"``, ``"failed"`` (the job
    raised) or ``"not driven"``; metrics and changes against the baseline only when it ran."""

    track: str
    seed: int
    controller: str
    ok: bool
    error: str | None
    status: str
    completed: bool
    metrics: dict[str, Any] = field(default_factory=dict)
    change_pct: dict[str, float | None] | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "track": self.track,
            "seed": self.seed,
            "controller": self.controller,
            "ok": self.ok,
            "error": self.error,
            "status": self.status,
            "completed": self.completed,
        }
        if self.status == "ran":
            out.update(self.metrics)
            out["change_pct"] = dict(self.change_pct or {})
        return out


@dataclass(frozen=True)
class ControllerSummary:
    """One controller over many run groups.

    ``jobs`` groups in all, ``runs`` laps driven, ``completed`` laps completed,
    ``failed_jobs`` groups whose job raised (no lap, counted as not completed),
    ``missing`` groups that ran without it; ``metrics`` the statistics of each
    metric over the completed laps (``progress`` over every lap driven);
    ``change_pct`` the statistics of the change in % against the baseline over
    the groups where both laps are complete.
    """

    jobs: int
    runs: int
    completed: int
    failed_jobs: int
    missing: int
    metrics: dict[str, Stats]
    change_pct: dict[str, Stats]

    def to_json(self) -> dict[str, Any]:
        return {
            "jobs": self.jobs,
            "runs": self.runs,
            "completed": self.completed,
            "failed_jobs": self.failed_jobs,
            "missing": self.missing,
            "metrics": {k: s.to_json() for k, s in self.metrics.items()},
            "change_pct": {k: s.to_json() for k, s in self.change_pct.items()},
        }


def _row(group: RunGroup, name: str, baseline: str | None) -> RunRow:
    if not group.ok or name not in group.metrics:
        status = "failed" if not group.ok else "not driven"
        return RunRow(group.track, group.seed, name, group.ok, group.error, status=status, completed=False)
    m = group.metrics[name]
    done = bool(m["completed"])
    changes: dict[str, float | None] = {}
    base = group.metrics[baseline] if baseline is not None and baseline in group.metrics else None
    if base is not None:
        both = done and bool(base["completed"])
        changes = {k: change_pct(m[k], base[k]) if both else None for k in CHANGE_METRICS}
    metrics = {k: m[k] for k in SUMMARY_METRICS}
    return RunRow(
        group.track, group.seed, name, group.ok, group.error, "ran", done, metrics=metrics, change_pct=changes
    )


def summarise_runs(
    groups: Sequence[RunGroup], controllers: Sequence[str], baseline: str | None = "lmpc"
) -> tuple[dict[str, ControllerSummary], list[RunRow]]:
    """Per-controller summaries and flat rows (group order, then controller order) of run groups."""
    rows = [_row(group, name, baseline) for group in groups for name in controllers]
    summary: dict[str, ControllerSummary] = {}
    for name in controllers:
        mine = [row for row in rows if row.controller == name]
        ran = [row for row in mine if row.status == "ran"]
        done = [row for row in ran if row.completed]
        metrics = {k: stats(row.metrics[k] for row in done) for k in SUMMARY_METRICS}
        metrics["progress"] = stats(row.metrics["progress"] for row in ran)
        changes: dict[str, Stats] = {}
        if baseline is not None:
            with_base = [row for row in ran if row.change_pct]
            changes = {
                k: stats(row.change_pct[k] for row in with_base if row.change_pct) for k in CHANGE_METRICS
            }
        summary[name] = ControllerSummary(
            jobs=len(mine),
            runs=len(ran),
            completed=len(done),
            failed_jobs=sum(row.status == "failed" for row in mine),
            missing=sum(row.status == "not driven" for row in mine),
            metrics={k: metrics[k] for k in SUMMARY_METRICS},
            change_pct=changes,
        )
    return summary, rows
