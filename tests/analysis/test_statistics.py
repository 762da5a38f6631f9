"""Statistics over runs: summaries and relative changes."""

from __future__ import annotations

import math

import pytest

from rkmpc.analysis.statistics import Stats, change_pct, stats


def test_stats_leave_out_missing_values():
    s = stats([1.0, 2.0, None, float("nan"), 6.0])
    assert (s.n, s.mean, s.min, s.max) == (3, 3.0, 1.0, 6.0)
    assert s.std == pytest.approx(math.sqrt(7.0))
    assert stats([2.0]).std is None
    assert stats([]) == Stats(n=0, mean=None, std=None, min=None, max=None)
    assert stats([]).to_json() == {"n": 0, "mean": None, "std": None, "min": None, "max": None}


def test_change_pct():
    assert change_pct(0.8, 1.0) == pytest.approx(-20.0)
    assert change_pct(1.0, 0.0) is None and change_pct(None, 1.0) is None
    assert change_pct(float("inf"), 1.0) is None
