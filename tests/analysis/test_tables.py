"""Result tables: cell formatting, changes against the baseline, Markdown and rich tables."""

from __future__ import annotations

import pytest

from rkmpc.analysis.metrics import METRIC_KEYS
from rkmpc.analysis.statistics import Stats
from rkmpc.analysis.tables import (
    TABLE_COLUMNS,
    change_vs,
    fault_table,
    fmt,
    fmt_stats,
    format_cell,
    markdown,
    markdown_table,
    rich_table,
)

N_COLUMNS = 1 + len(TABLE_COLUMNS)  # controller + metrics


def _metrics(lat: float | None, head: float, rate: float, **changes) -> dict:
    m = {
        "completed": True,
        "progress": 1.0,
        "lap_time_s": 25.123,
        "lateral_error_mean_m": lat,
        "lateral_error_max_m": 0.1234,
        "heading_error_mean_rad": head,
        "steer_rate_mean_rad_s": rate,
        "command_rate_mean_rad_s": rate,
        "solve_ms_mean": 1.5,
        "solve_ms_p99": 3.25,
        "solve_ms_max": 4.0,
        "fallback_count": 0,
        "steps": 500,
        "lateral_accel_max_m_s2": 3.96,
    }
    m.update(changes)
    return m


RESULTS = {
    "pp": _metrics(0.05, 0.02, 0.5),
    "lmpc": _metrics(0.04, 0.01, 0.25),
    "rkmpc": _metrics(0.03, 0.012, 0.2, completed=False, progress=0.456, lap_time_s=None, fallback_count=3),
}


def _cells(line: str) -> list[str]:
    assert line.startswith("| ") and line.endswith(" |")
    return line[2:-2].split(" | ")


# ---------------------------------------------------------------------------- cells


def test_format_cell():
    assert format_cell(None, "{:.3f}") == "-"
    assert format_cell(True, "{}") == "yes"
    assert format_cell(False, "{}") == "NO"
    assert format_cell(0.123456, "{:.4f}") == "0.1235"
    assert format_cell(0.456, "{:.0%}") == "46%"
    assert format_cell(3, "{}") == "3"
    assert format_cell(0, "{}") == "0"  # a zero is a number, not a missing value


def test_change_vs():
    base = {"lat": 0.04, "zero": 0.0, "none": None}
    assert change_vs({"lat": 0.03}, base, "lat") == "-25.0%"
    assert change_vs({"lat": 0.05}, base, "lat") == "+25.0%"
    assert change_vs({"lat": 0.04}, base, "lat") == "+0.0%"
    assert change_vs({"zero": 1.0}, base, "zero") == "-"
    assert change_vs({"none": 1.0}, base, "none") == "-"
    assert change_vs({"lat": None}, base, "lat") == "-"
    with pytest.raises(KeyError):
        change_vs({}, base, "lat")


def test_fmt():
    assert fmt(None) == "-"
    assert fmt(0.123456) == "0.1235"
    assert fmt(2.0, ".1f") == "2.0"
    assert fmt(-0.5, "+.2f") == "-0.50"


def test_fmt_stats():
    assert fmt_stats(None) == "-"
    assert fmt_stats(Stats(n=0, mean=None, std=None, min=None, max=None)) == "-"
    assert fmt_stats(Stats(n=1, mean=0.5, std=None, min=0.5, max=0.5)) == "0.5000"
    assert fmt_stats(Stats(n=3, mean=0.5, std=0.1, min=0.4, max=0.6), ".2f") == "0.50 ± 0.10 [0.40, 0.60]"
    assert fmt_stats(Stats(n=3, mean=5.0, std=1.0, min=-4.0, max=6.0), ".1f", pct=True) == (
        "+5.0% ± 1.0 [-4.0, +6.0]"
    )
    assert fmt_stats(Stats(n=1, mean=-5.0, std=None, min=-5.0, max=-5.0), ".1f", pct=True) == "-5.0%"


# ---------------------------------------------------------------------------- Markdown


def test_markdown():
    text = markdown(["a", "b"], [["1", "2"], ["x", "y"]])
    assert text == "| a | b |\n|---|---|\n| 1 | 2 |\n| x | y |\n"
    assert markdown(["only"], []) == "| only |\n|---|\n"


def test_markdown_table_with_baseline():
    text = markdown_table(RESULTS)
    lines = text.splitlines()
    assert text.endswith("\n")
    assert len(lines) == 2 + len(RESULTS)
    header = _cells(lines[0])
    assert header[0] == "controller"
    assert header[1:-1] == [title for _, title, _ in TABLE_COLUMNS]
    assert header[-1] == "vs LMPC: lat / head / rate"
    assert lines[1] == "|" + "---|" * (N_COLUMNS + 1)
    rows = {cells[0]: cells for cells in map(_cells, lines[2:])}
    assert list(rows) == list(RESULTS)
    assert all(len(cells) == N_COLUMNS + 1 for cells in rows.values())
    pp = dict(zip(header, rows["pp"], strict=True))
    assert pp["done"] == "yes"
    assert pp["lap %"] == "100%"
    assert pp["lat. err (m)"] == "0.0500"
    assert pp["lat. max (m)"] == "0.123"
    assert pp["t p99 (ms)"] == "3.250"
    assert pp["lap (s)"] == "25.12"
    assert pp["peak a_y (m/s²)"] == "4.0"
    assert pp["vs LMPC: lat / head / rate"] == "+25.0% / +100.0% / +100.0%"
    rk = dict(zip(header, rows["rkmpc"], strict=True))
    assert rk["done"] == "NO"
    assert rk["lap %"] == "46%"
    assert rk["lap (s)"] == "-"
    assert rk["fallbacks"] == "3"
    assert rk["vs LMPC: lat / head / rate"] == "-25.0% / +20.0% / -20.0%"
    assert rows["lmpc"][-1] == "+0.0% / +0.0% / +0.0%"


def test_markdown_table_without_baseline():
    results = {k: v for k, v in RESULTS.items() if k != "lmpc"}
    for text in (markdown_table(results), markdown_table(RESULTS, baseline=None)):
        lines = text.splitlines()
        assert "vs LMPC" not in lines[0]
        assert len(_cells(lines[0])) == N_COLUMNS
        assert lines[1] == "|" + "---|" * N_COLUMNS
        assert all(len(_cells(line)) == N_COLUMNS for line in lines[2:])
    assert len(markdown_table(results).splitlines()) == 2 + 2


def test_markdown_table_with_another_baseline():
    lines = markdown_table(RESULTS, baseline="pp").splitlines()
    rows = {cells[0]: cells for cells in map(_cells, lines[2:])}
    assert rows["pp"][-1] == "+0.0% / +0.0% / +0.0%"
    assert rows["lmpc"][-1] == "-20.0% / -50.0% / -50.0%"


def test_markdown_table_missing_value_shows_a_dash():
    results = {"lmpc": _metrics(0.04, 0.01, 0.25), "kmpc": _metrics(None, 0.01, 0.25)}
    lines = markdown_table(results).splitlines()
    kmpc = _cells(lines[3])
    assert kmpc[0] == "kmpc"
    assert kmpc[1 + [k for k, _, _ in TABLE_COLUMNS].index("lateral_error_mean_m")] == "-"
    assert kmpc[-1] == "- / +0.0% / +0.0%"


def test_table_columns_are_metrics():
    assert {key for key, _, _ in TABLE_COLUMNS} <= set(METRIC_KEYS)


def test_fault_table():
    nominal = {"lmpc": _metrics(0.04, 0.01, 0.25), "rkmpc": _metrics(0.02, 0.01, 0.2)}
    faulted = {
        "lmpc": _metrics(0.05, 0.02, 0.3, fallback_count=4),
        "rkmpc": _metrics(0.01, 0.015, 0.2, progress=0.5, lateral_error_max_m=None),
    }
    text = fault_table(nominal, faulted, {"lmpc": "degraded"}, "delay")
    lines = text.splitlines()
    assert len(lines) == 2 + 2
    header = _cells(lines[0])
    assert header[:3] == ["controller", "with delay", "lap %"]
    assert len(header) == 8
    assert lines[1] == "|" + "---|" * 8
    lmpc = _cells(lines[2])
    assert lmpc == ["lmpc", "degraded", "100%", "0.0400 -> 0.0500", "+25.0%", "0.123", "0.0200", "4"]
    rk = _cells(lines[3])
    assert rk == ["rkmpc", "-", "50%", "0.0200 -> 0.0100", "-50.0%", "-", "0.0150", "0"]


def test_fault_table_rows_follow_the_faulted_runs():
    nominal = {"lmpc": _metrics(0.04, 0.01, 0.25), "pp": _metrics(0.05, 0.01, 0.25)}
    faulted = {"pp": _metrics(0.05, 0.01, 0.25)}
    lines = fault_table(nominal, faulted, {}, "noise").splitlines()
    assert len(lines) == 3 and _cells(lines[2])[0] == "pp"
    with pytest.raises(KeyError):
        fault_table({}, faulted, {}, "noise")


# ---------------------------------------------------------------------------- rich


def test_rich_table_with_baseline():
    from rich.table import Table

    table = rich_table(RESULTS, "builtin")
    assert isinstance(table, Table)
    assert table.title == "builtin"
    assert len(table.columns) == N_COLUMNS + 1
    assert table.row_count == len(RESULTS)
    assert next(c.header for c in table.columns) == "controller"
    assert table.columns[-1].header == "vs LMPC: lat / head / rate"
    assert list(table.columns[0].cells) == list(RESULTS)
    assert list(table.columns[1].cells) == ["yes", "yes", "NO"]


def test_rich_table_without_baseline():
    results = {k: v for k, v in RESULTS.items() if k != "lmpc"}
    table = rich_table(results, "t", baseline="lmpc")
    assert len(table.columns) == N_COLUMNS
    assert table.row_count == 2
    # The baseline alone: nothing to compare against.
    alone = rich_table({"lmpc": RESULTS["lmpc"]}, "t")
    assert len(alone.columns) == N_COLUMNS
    assert alone.row_count == 1
    assert len(rich_table(RESULTS, "t", baseline=None).columns) == N_COLUMNS


def test_the_table_fits_a_narrow_terminal_without_cutting_a_cell():
    from rich.console import Console

    from rkmpc.analysis.tables import rich_tables_fitting

    assert len(rich_tables_fitting(RESULTS, "builtin", width=400)) == 1  # wide enough: as it was
    tables = rich_tables_fitting(RESULTS, "builtin", width=80)
    console = Console(width=80, record=True)
    for table in tables:
        console.print(table)
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80
    assert "…" not in text  # rich marks a cut cell with an ellipsis
    for name in RESULTS:
        assert name in text


def test_a_completed_lap_that_slid_is_flagged_and_said(capsys):
    """peak a_y 19.1 m/s^2 on a lap marked done with a 5 m/s^2 limit (a slide at the finish): flagged."""
    from rich.console import Console

    from rkmpc.analysis.tables import SLIDE_FACTOR, rich_tables_fitting, slid

    results = {
        "lmpc": _metrics(0.04, 0.01, 0.25, lateral_accel_max_m_s2=8.2),  # 1.6 x: transients of a clean lap
        "rkmpc": _metrics(0.03, 0.01, 0.2, lateral_accel_max_m_s2=19.1),
        "pp": _metrics(
            0.05, 0.02, 0.5, completed=False, lateral_accel_max_m_s2=30.0
        ),  # off: not a "done" lap
    }
    assert SLIDE_FACTOR == 2.0
    assert [slid(m, 5.0) for m in results.values()] == [False, True, False]
    assert not any(slid(m, None) for m in results.values())  # no limit known: nothing flagged
    text = markdown_table(results, lateral_limit=5.0)
    rows = {
        _cells(line)[0]: _cells(line)
        for line in text.splitlines()
        if line.startswith("| ") and "---" not in line
    }
    assert rows["rkmpc"][N_COLUMNS - 1] == "19.1 !" and rows["lmpc"][N_COLUMNS - 1] == "8.2"
    assert rows["pp"][N_COLUMNS - 1] == "30.0"
    note = "! peak a_y beyond 2 x the pace's lateral limit (5 m/s²) on a completed lap (rkmpc): the car slid"
    assert text.rstrip().splitlines()[-1] == note
    assert "!" not in markdown_table(results)  # without the limit, as before
    for width in (80, 300):  # the wide table and the tables on their side
        console = Console(width=width, record=True, file=None)
        for table in rich_tables_fitting(results, "builtin", width, lateral_limit=5.0):
            console.print(table)
        shown = console.export_text()
        assert "19.1 !" in shown and " ".join(note.split()) in " ".join(shown.split())


def test_a_run_that_never_started_reads_not_driven_not_a_failed_lap():
    from rkmpc.analysis.metrics import LapMetrics

    results = {"lmpc": RESULTS["lmpc"], "rkmpc": LapMetrics.not_driven()}
    cells = _cells(markdown_table(results).splitlines()[3])
    assert cells[:3] == ["rkmpc", "not driven", "-"]
    # A lap that started and failed still reads NO with its progress.
    failed = _cells(markdown_table(RESULTS).splitlines()[4])
    assert failed[:3] == ["rkmpc", "NO", "46%"]
