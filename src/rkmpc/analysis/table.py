"""Tables of metrics per controller, as text, Markdown and rich tables."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: (metric key, column title, format) of the comparison table.
TABLE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("completed", "done", "{}"),
    ("progress", "lap %", "{:.0%}"),
    ("lateral_error_mean_m", "lat. err (m)", "{:.4f}"),
    ("lateral_error_max_m", "lat. max (m)", "{:.3f}"),
    ("heading_error_mean_rad", "head. err (rad)", "{:.4f}"),
    ("steer_rate_mean_rad_s", "wheel rate (rad/s)", "{:.4f}"),
    ("solve_ms_mean", "t mean (ms)", "{:.3f}"),
    ("solve_ms_p99", "t p99 (ms)", "{:.3f}"),
    ("solve_ms_max", "t max (ms)", "{:.3f}"),
    ("lap_time_s", "lap (s)", "{:.2f}"),
    ("fallback_count", "fallbacks", "{}"),
    ("lateral_accel_max_m_s2", "peak a_y (m/s²)", "{:.1f}"),
)

_CHANGE_KEYS = ("lateral_error_mean_m", "heading_error_mean_rad", "steer_rate_mean_rad_s")


def format_cell(value: Any, fmt: str) -> str:
    """Format one metric; None shows as a dash."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    return fmt.format(value)


def change_vs(metrics: Mapping[str, Any], baseline: Mapping[str, Any], key: str) -> str:
    """Relative change of ``key`` against the baseline, in percent, as text."""
    a, b = metrics.get(key), baseline.get(key)
    if a is None or b is None or b == 0:
        return "-"
    return f"{100.0 * (a - b) / b:+.1f}%"


def table_rows(results: Mapping[str, Mapping[str, Any]], baseline: str | None = "lmpc") -> list[list[str]]:
    """Rows (controller, cells..., changes vs baseline) of the comparison table."""
    rows = []
    base = results.get(baseline) if baseline else None
    for name, metrics in results.items():
        row = [name] + [format_cell(metrics[key], fmt) for key, _, fmt in TABLE_COLUMNS]
        if base is not None:
            row.append(" / ".join(change_vs(metrics, base, k) for k in _CHANGE_KEYS))
        rows.append(row)
    return rows


def table_header(with_change: bool) -> list[str]:
    """Column titles of :func:`table_rows`."""
    header = ["controller"] + [title for _, title, _ in TABLE_COLUMNS]
    if with_change:
        header.append("vs LMPC: lat / head / rate")
    return header


def markdown_table(results: Mapping[str, Mapping[str, Any]], baseline: str | None = "lmpc") -> str:
    """The comparison table in Markdown."""
    with_change = bool(baseline) and baseline in results
    header = table_header(with_change)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in table_rows(results, baseline if with_change else None):
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def fault_table(
    nominal: Mapping[str, Mapping[str, Any]],
    faulted: Mapping[str, Mapping[str, Any]],
    effects: Mapping[str, str],
    fault: str,
) -> str:
    """Markdown table of what a fault did to each controller.

    Parameters
    ----------
    nominal, faulted : mapping of str to metrics
        :func:`rkmpc.analysis.metrics.lap_metrics` of each controller without and with the fault.
    effects : mapping of str to str
        Classification per controller (:func:`rkmpc.experiments.learned.fault_effect`).
    fault : str
        Name of the fault, for the title row.
    """
    header = [
        "controller",
        f"with {fault}",
        "lap %",
        "lat. err (m) nominal -> fault",
        "change",
        "lat. max (m) with fault",
        "head. err (rad) with fault",
        "fallbacks with fault",
    ]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for name, fm in faulted.items():
        nm = nominal[name]
        lat = (
            f"{format_cell(nm['lateral_error_mean_m'], '{:.4f}')} -> "
            f"{format_cell(fm['lateral_error_mean_m'], '{:.4f}')}"
        )
        cells = [
            name,
            effects.get(name, "-"),
            format_cell(fm["progress"], "{:.0%}"),
            lat,
            change_vs(fm, nm, "lateral_error_mean_m"),
            format_cell(fm["lateral_error_max_m"], "{:.3f}"),
            format_cell(fm["heading_error_mean_rad"], "{:.4f}"),
            format_cell(fm["fallback_count"], "{}"),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
