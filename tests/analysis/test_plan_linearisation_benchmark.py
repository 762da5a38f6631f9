"""benchmarks/plan_linearisation.py: the LMPC along the reference against the LMPC about its plan."""

from __future__ import annotations


def test_a_row_drives_both_linearisations_and_reports_the_change(benchmark_script):
    script = benchmark_script("plan_linearisation")
    cells = script.row("builtin").split(" | ")
    assert cells[1] == "completed / completed"
    reference, plan = (float(x) for x in cells[2].split(" (")[0].split(" / "))
    assert plan < reference  # the table's claim on the built-in track
    assert cells[2].endswith("%)") and "(-" in cells[2]
