"""Tests of rkmpc.track.track."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.track import Path, Track


def ring(radius: float) -> Path:
    th = np.linspace(0.0, 2 * np.pi, 80, endpoint=False)
    return Path.from_points(np.column_stack([radius * np.cos(th), radius * np.sin(th)]))


def test_widths_scalar_array_callable() -> None:
    c = ring(10.0)
    const = Track("c", c, 1.0, 2.0)
    assert const.width_right(5.0) == pytest.approx(1.0)
    assert const.width_left(5.0) == pytest.approx(2.0)
    arr = Track("a", c, np.array([1.0, 2.0, 3.0, 4.0]), 1.0)
    quarter = c.length / 4
    assert arr.width_right(quarter) == pytest.approx(2.0)
    assert arr.width_right(0.5 * quarter) == pytest.approx(1.5)
    assert arr.width_right(3.5 * quarter) == pytest.approx(2.5)  # wraps back to the first value
    assert arr.width_right(-0.5 * quarter) == pytest.approx(2.5)
    fun = Track("f", c, lambda s: 1.0 + 0.0 * s, lambda s: 0.5 + s / c.length)
    assert fun.width_left(c.length / 2) == pytest.approx(1.0)
    np.testing.assert_allclose(fun.width_right(np.array([0.0, 1.0])), 1.0)
    for bad in (0.0, -1.0, np.array([1.0, 0.0]), np.array([1.0, np.nan]), lambda s: s - 1.0):
        with pytest.raises(ParameterError):
            Track("bad", c, bad, 1.0)


def test_inside_and_boundary_offsets() -> None:
    # Counter-clockwise ring of radius 10: left is towards the centre.
    tr = Track("ring", ring(10.0), 1.0, 2.0)
    s, lat, margin = tr.boundary_offsets(10.5, 0.0)
    assert s == pytest.approx(0.0, abs=1e-6) or s == pytest.approx(tr.length, abs=1e-6)
    assert lat == pytest.approx(-0.5, abs=1e-6)
    assert margin == pytest.approx(0.5, abs=1e-6)
    assert tr.is_inside(10.5, 0.0)
    assert tr.is_inside(0.0, 8.5, s_hint=tr.length / 4)
    assert not tr.is_inside(11.2, 0.0)
    assert not tr.is_inside(7.5, 0.0, s_hint=0.1)
    assert tr.boundary_offsets(0.0, 7.5)[2] == pytest.approx(-0.5, abs=1e-6)


def test_boundaries_and_reference_path() -> None:
    c = ring(10.0)
    tr = Track("ring", c, 1.0, 2.0)
    left, right = tr.boundaries(0.5)
    np.testing.assert_allclose(np.hypot(*left.T), 8.0, atol=1e-4)
    np.testing.assert_allclose(np.hypot(*right.T), 11.0, atol=1e-4)
    assert tr.reference_path is c
    race = ring(9.5)
    tr2 = tr.with_raceline(race)
    assert tr2.reference_path is race and tr.raceline is None
    assert tr2.width_left(1.0) == pytest.approx(2.0)
    with pytest.raises(ParameterError):
        Track("x", c, 1.0, 1.0, scale=0.0)


def test_a_race_line_off_the_track_is_refused() -> None:
    """A race line 500 m away (another track, unit or scale) would be tracked with 'no error'."""
    th = np.linspace(0.0, 2 * np.pi, 80, endpoint=False)
    far = Path.from_points(np.column_stack([500 + 9.5 * np.cos(th), 9.5 * np.sin(th)]), source="far.csv")
    with pytest.raises(ParameterError, match=r"far\.csv leaves the track.*outside its boundary"):
        Track("ring", ring(10.0), 1.0, 2.0, raceline=far)
    # Near the boundary (0.5 m outside a 3 m wide track) is still a race line.
    Track("ring", ring(10.0), 1.0, 2.0, raceline=ring(11.5))
