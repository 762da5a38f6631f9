"""The tables of the tracks and cars studies: a summary per controller and one row per run."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from rkmpc.analysis.statistics import ControllerSummary, RunRow
from rkmpc.analysis.tables import fmt, fmt_stats, markdown

__all__ = ["runs_table", "summary_table"]


#: Columns of the tracks tables: metric, header, number format.
_TRACK_COLUMNS = (
    ("lateral_error_mean_m", "lat (m)", ".4f"),
    ("lateral_error_max_m", "lat max (m)", ".3f"),
    ("heading_error_mean_rad", "head (rad)", ".4f"),
    ("steer_rate_mean_rad_s", "rate (rad/s)", ".4f"),
    ("command_rate_mean_rad_s", "cmd rate (rad/s)", ".4f"),
)
_SOLVE = ("solve_ms_mean", "solve_ms_p99", "solve_ms_max")


def summary_table(
    summary: Mapping[str, ControllerSummary], controllers: Sequence[str], baseline: str | None
) -> str:
    """Markdown: one row per controller, ``mean ± std [min, max]`` of each metric (change vs baseline)."""
    head = ["controller", "completed", "failed jobs"]
    for _, label, _ in _TRACK_COLUMNS:
        head.append(label)
        if baseline:
            head.append(f"{label.split(' ')[0]} vs {baseline}")
    head += ["solve mean (ms)", "solve p99 (ms)", "solve max (ms)"]
    rows = []
    for name in controllers:
        s = summary[name]
        cells = [name, f"{s.completed}/{s.jobs}", str(s.failed_jobs)]
        for key, _, spec in _TRACK_COLUMNS:
            cells.append(fmt_stats(s.metrics[key], spec))
            if baseline:
                cells.append(fmt_stats(s.change_pct[key] if key in s.change_pct else None, ".1f", pct=True))
        cells += [fmt_stats(s.metrics[key], ".2f") for key in _SOLVE]
        rows.append(cells)
    return markdown(head, rows)


def _row_cells(row: RunRow, baseline: str | None) -> list[str]:
    cells = [row.track, str(row.seed), row.controller]
    if row.status != "ran":
        error = str(row.error or "").splitlines()
        cells.append("FAILED: " + error[0][:80].replace("|", "/") if error else row.status)
        return cells + ["-"] * (len(_TRACK_COLUMNS) + 2 + (1 if baseline else 0))
    progress = row.metrics["progress"]
    cells.append("yes" if row.completed else "NO " + format(progress or 0.0, ".0%"))
    cells += [fmt(row.metrics[k], spec) for k, _, spec in _TRACK_COLUMNS]
    if baseline:
        ch = row.change_pct or {}
        changes = [ch[k] if k in ch else None for k, _, _ in _TRACK_COLUMNS]
        cells.append(" / ".join("-" if c is None else f"{c:+.0f}%" for c in changes))
    cells.append(" / ".join(fmt(row.metrics[k], ".2f") for k in _SOLVE))
    return cells


def runs_table(rows: Sequence[RunRow], baseline: str | None) -> str:
    """Markdown: one row per run (track, seed, controller) with its metrics and changes."""
    head = ["track", "seed", "controller", "done", *(label for _, label, _ in _TRACK_COLUMNS)]
    if baseline:
        head.append(f"vs {baseline}: " + " / ".join(label.split(" (")[0] for _, label, _ in _TRACK_COLUMNS))
    head.append("t mean / p99 / max (ms)")
    return markdown(head, [_row_cells(row, baseline) for row in rows])
