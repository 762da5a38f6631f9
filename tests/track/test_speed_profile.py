"""Tests of rkmpc.track.speed_profile."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.track import Path, SpeedLimits, builtin_track, speed_profile


@pytest.fixture(scope="module")
def path() -> Path:
    return builtin_track().centerline


def test_limits_validation() -> None:
    SpeedLimits()
    for bad in (
        {"lateral_accel": 0.0},
        {"brake_decel": -1.0},
        {"accel": float("nan")},
        {"max_speed": float("inf")},
        {"min_speed": 6.0},
    ):
        with pytest.raises(ParameterError):
            SpeedLimits(**bad)


@pytest.mark.parametrize(
    "limits", [SpeedLimits(), SpeedLimits(lateral_accel=8.0, brake_decel=4.0, accel=1.0, max_speed=9.0)]
)
def test_profile_respects_limits(path: Path, limits: SpeedLimits) -> None:
    prof = speed_profile(path, limits)
    s, v = prof.s, prof.v
    ds = s[1] - s[0]
    np.testing.assert_allclose(np.diff(s), ds)
    assert s[0] == 0.0 and s[-1] < path.length
    assert np.all(v <= limits.max_speed + 1e-12)
    assert np.all(v >= limits.min_speed - 1e-12)
    # Lateral limit at the grid points.
    kappa = np.abs(np.asarray(path.curvature(s)))
    assert np.all(v**2 * kappa <= limits.lateral_accel * (1 + 1e-9))
    # Acceleration and braking between consecutive points, including across the start line.
    v2 = np.append(v, v[0]) ** 2
    dv2 = np.diff(v2)
    assert np.all(dv2 <= 2 * limits.accel * ds + 1e-9)
    assert np.all(-dv2 <= 2 * limits.brake_decel * ds + 1e-9)
    # The profile is not trivially slow: it reaches the top speed or the curvature limit somewhere.
    assert v.max() > 0.9 * limits.max_speed or np.any(v**2 * kappa > 0.9 * limits.lateral_accel)
    assert prof.lap_time == pytest.approx(np.sum(ds / v), rel=0.02)


def test_periodic_interpolation(path: Path) -> None:
    prof = speed_profile(path, SpeedLimits(), ds=0.2)
    assert prof.speed(0.0) == pytest.approx(prof.v[0])
    assert prof.speed(path.length) == pytest.approx(prof.v[0])
    assert prof.speed(-0.1) == pytest.approx(prof.speed(path.length - 0.1))
    np.testing.assert_allclose(prof.speed(prof.s + 3 * path.length), prof.v, atol=1e-9)


def test_circle_constant_speed() -> None:
    th = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    circle = Path.from_points(np.column_stack([2 * np.cos(th), 2 * np.sin(th)]))
    prof = speed_profile(circle, SpeedLimits(lateral_accel=2.0, max_speed=10.0))
    np.testing.assert_allclose(prof.v, 2.0, rtol=1e-3)
    assert prof.lap_time == pytest.approx(circle.length / 2.0, rel=1e-3)


def test_min_speed_floor(path: Path) -> None:
    prof = speed_profile(path, SpeedLimits(lateral_accel=0.05, min_speed=0.6, max_speed=5.0))
    assert prof.v.min() == pytest.approx(0.6)


def test_curvature_smoothing(path: Path) -> None:
    limits = SpeedLimits()
    raw = speed_profile(path, limits)
    smooth = speed_profile(path, limits, curvature_smoothing=1.0)
    assert smooth.lap_time < raw.lap_time  # smoothing lowers curvature peaks
    assert smooth.lap_time > 0.9 * raw.lap_time
    with pytest.raises(ParameterError):
        speed_profile(path, limits, curvature_smoothing=-1.0)


def test_limits_at_another_pace_scale_braking_and_traction_with_the_lateral_limit():
    base = SpeedLimits(
        lateral_accel=4.0, brake_decel=2.5, accel=2.0, max_speed=3.5, min_speed=0.5, curvature_rate=1.0
    )
    race = base.at_pace(lateral_accel=6.0, max_speed=5.0)
    assert (race.lateral_accel, race.max_speed) == (6.0, 5.0)
    assert race.brake_decel == pytest.approx(3.75) and race.accel == pytest.approx(3.0)
    assert (race.min_speed, race.curvature_rate) == (0.5, 1.0)
    assert base.at_pace() == base
    assert base.at_pace(max_speed=4.0).brake_decel == base.brake_decel
    with pytest.raises(ParameterError, match="lateral_accel"):
        base.at_pace(lateral_accel=-1.0)
    with pytest.raises(ParameterError, match="min_speed"):
        base.at_pace(max_speed=0.4)
