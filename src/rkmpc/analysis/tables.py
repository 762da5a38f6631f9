"""Tables: the comparison table of controllers (Markdown and rich), and the Markdown primitives
that every result table of the package is written with.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from rkmpc.analysis.statistics import Stats, change_pct

#: (metric key, column title, format) of the comparison table.
TABLE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("completed", "done", "{}"),
    ("progress", "lap %", "{:.0%}"),
    ("lateral_error_mean_m", "lat. err (m)", "{:.4f}"),
    ("lateral_error_max_m", "lat. max (m)", "{:.3f}"),
    ("heading_error_mean_rad", "head. err (rad)", "{:.4f}"),
    ("steer_rate_mean_rad_s", "wheel rate (rad/s)", "{:.4f}"),
    ("command_rate_mean_rad_s", "cmd rate (rad/s)", "{:.4f}"),
    ("solve_ms_mean", "t mean (ms)", "{:.3f}"),
    ("solve_ms_p99", "t p99 (ms)", "{:.3f}"),
    ("solve_ms_max", "t max (ms)", "{:.3f}"),
    ("lap_time_s", "lap (s)", "{:.2f}"),
    ("fallback_count", "fallbacks", "{}"),
    ("lateral_accel_max_m_s2", "peak a_y (m/s²)", "{:.1f}"),
)

_CHANGE_KEYS = ("lateral_error_mean_m", "heading_error_mean_rad", "steer_rate_mean_rad_s")

#: A completed lap whose peak lateral acceleration is beyond this multiple of the pace's lateral
#: limit slid somewhere (at the finish, often): its cell is flagged with :data:`SLIDE_MARK`. The
#: clean laps of PP and the LMPC peak at up to 1.7 times the limit on every shared track
#: (``docs/baselines.md``: the peak is of speed x yaw rate, transients included).
SLIDE_FACTOR = 2.0
SLIDE_MARK = " !"
#: The "done" cell of a run that never started (no step driven).
NOT_DRIVEN = "not driven"
#: Positions of the "done" and "lap %" cells in a row of :func:`table_rows` (the name comes first).
_KEYS = [key for key, _, _ in TABLE_COLUMNS]
_DONE_CELL, _PROGRESS_CELL = 1 + _KEYS.index("completed"), 1 + _KEYS.index("progress")


def slid(metrics: Mapping[str, Any], lateral_limit: float | None) -> bool:
    """Whether a completed lap's peak lateral acceleration is beyond :data:`SLIDE_FACTOR` times the limit."""
    peak = metrics["lateral_accel_max_m_s2"]
    return bool(
        lateral_limit is not None
        and metrics["completed"]
        and peak is not None
        and peak > SLIDE_FACTOR * lateral_limit
    )


def slide_note(results: Mapping[str, Mapping[str, Any]], lateral_limit: float | None) -> str | None:
    """The line under a table with flagged peaks: which controllers, and what the flag means."""
    flagged = [name for name, metrics in results.items() if slid(metrics, lateral_limit)]
    if not flagged:
        return None
    return (
        f"{SLIDE_MARK.strip()} peak a_y beyond {SLIDE_FACTOR:g} x the pace's lateral limit "
        f"({lateral_limit:g} m/s²) on a completed lap ({', '.join(flagged)}): the car slid"
    )


def format_cell(value: Any, fmt: str) -> str:
    """Format one metric; None shows as a dash."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    return fmt.format(value)


def change_vs(metrics: Mapping[str, Any], baseline: Mapping[str, Any], key: str) -> str:
    """Relative change of ``key`` against the baseline, in percent, as text."""
    change = change_pct(metrics[key], baseline[key])
    return "-" if change is None else f"{change:+.1f}%"


def table_rows(
    results: Mapping[str, Mapping[str, Any]],
    baseline: str | None = "lmpc",
    lateral_limit: float | None = None,
) -> list[list[str]]:
    """Rows (controller, cells..., changes vs baseline) of the comparison table.

    With the pace's ``lateral_limit`` (m/s^2), a completed lap's peak lateral acceleration beyond
    :data:`SLIDE_FACTOR` times it is flagged (:func:`slid`).
    """
    rows = []
    base = results[baseline] if baseline and baseline in results else None
    for name, metrics in results.items():
        row = [name] + [format_cell(metrics[key], fmt) for key, _, fmt in TABLE_COLUMNS]
        if metrics["steps"] == 0:  # never started (a learned controller whose data were refused)
            row[_DONE_CELL] = NOT_DRIVEN
            row[_PROGRESS_CELL] = "-"
        if slid(metrics, lateral_limit):
            row[len(TABLE_COLUMNS)] += SLIDE_MARK
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


def markdown_table(
    results: Mapping[str, Mapping[str, Any]],
    baseline: str | None = "lmpc",
    lateral_limit: float | None = None,
) -> str:
    """The comparison table in Markdown (slides flagged and said below it, :func:`table_rows`)."""
    with_change = bool(baseline) and baseline in results
    text = markdown(
        table_header(with_change), table_rows(results, baseline if with_change else None, lateral_limit)
    )
    note = slide_note(results, lateral_limit)
    return text if note is None else f"{text}\n{note}\n"


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
        Classification per controller (:func:`rkmpc.experiments.compare.fault_effect`).
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
    rows = []
    for name, fm in faulted.items():
        nm = nominal[name]
        lat = (
            f"{format_cell(nm['lateral_error_mean_m'], '{:.4f}')} -> "
            f"{format_cell(fm['lateral_error_mean_m'], '{:.4f}')}"
        )
        cells = [
            name,
            effects[name] if name in effects else "-",
            format_cell(fm["progress"], "{:.0%}"),
            lat,
            change_vs(fm, nm, "lateral_error_mean_m"),
            format_cell(fm["lateral_error_max_m"], "{:.3f}"),
            format_cell(fm["heading_error_mean_rad"], "{:.4f}"),
            format_cell(fm["fallback_count"], "{}"),
        ]
        rows.append(cells)
    return markdown(header, rows)


def markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table: a header row, the separator and one line per row."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines.extend("| " + " | ".join(row) + " |" for row in rows)
    return "\n".join(lines) + "\n"


def fmt(value: float | None, spec: str = ".4f") -> str:
    """A number formatted with ``spec``; None shows as a dash."""
    return "-" if value is None else format(value, spec)


def fmt_stats(s: Stats | None, spec: str = ".4f", pct: bool = False) -> str:
    """``mean ± std [min, max]`` of :class:`Stats` (signed percentages when ``pct``); a dash for none."""
    if s is None or s.mean is None:
        return "-"
    sign = "+" if pct else ""
    unit = "%" if pct else ""
    text = f"{s.mean:{sign}{spec}}{unit}"
    if s.std is not None:
        text += f" ± {s.std:{spec}}"
    if s.n > 1 and s.min is not None and s.max is not None:
        text += f" [{s.min:{sign}{spec}}, {s.max:{sign}{spec}}]"
    return text


def rich_table(
    results: Mapping[str, Mapping[str, Any]],
    title: str,
    baseline: str | None = "lmpc",
    lateral_limit: float | None = None,
) -> Any:
    """The comparison table as a :class:`rich.table.Table` (changes against ``baseline`` when present)."""
    from rich.table import Table

    with_change = baseline is not None and baseline in results and len(results) > 1
    table = Table(title=title, caption=slide_note(results, lateral_limit))
    for col in table_header(with_change):
        table.add_column(col)
    for row in table_rows(results, baseline if with_change else None, lateral_limit):
        table.add_row(*row)
    return table


def rich_tables_fitting(
    results: Mapping[str, Mapping[str, Any]],
    title: str,
    width: int,
    baseline: str | None = "lmpc",
    lateral_limit: float | None = None,
) -> list[Any]:
    """The comparison as :class:`rich.table.Table` objects that fit ``width`` columns.

    The one wide table (:func:`rich_table`) when it fits; otherwise turned on its side (a row per
    metric, a column per controller), the controllers split over as many tables as it takes, so
    that no cell is cut in a narrow terminal.
    """
    from rich.console import Console
    from rich.table import Table

    wide = rich_table(results, title, baseline, lateral_limit)
    if Console(width=10_000).measure(wide).maximum <= width:
        return [wide]
    with_change = baseline is not None and baseline in results and len(results) > 1
    header = table_header(with_change)
    rows = table_rows(results, baseline if with_change else None, lateral_limit)
    columns = {row[0]: row[1:] for row in rows}
    if with_change:  # the changes against the baseline, one per row: narrow columns
        header = [*header[:-1], *(f"vs {baseline}: {what}" for what in ("lat", "head", "rate"))]
        columns = {name: [*cells[:-1], *cells[-1].split(" / ")] for name, cells in columns.items()}
    label = max(len(h) for h in header[1:]) + 3
    each = max(max(len(cell) for cell in [name, *cells]) + 3 for name, cells in columns.items())
    per_table = max(1, (width - label - 1) // each)
    names = list(columns)
    tables = []
    for start in range(0, len(names), per_table):
        group = names[start : start + per_table]
        table = Table(title=title if start == 0 else None)
        table.add_column("metric")
        for name in group:
            table.add_column(name)
        for i, metric in enumerate(header[1:]):
            table.add_row(metric, *(columns[name][i] for name in group))
        tables.append(table)
    tables[-1].caption = slide_note(results, lateral_limit)
    return tables
