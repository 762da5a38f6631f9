"""Tests of rkmpc.track.reference."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.errors import ParameterError
from rkmpc.track import Reference, SpeedLimits, builtin_track, speed_profile, wrap_angle

WHEELBASE = 0.307


@pytest.fixture(scope="module")
def reference() -> Reference:
    path = builtin_track().centerline
    return Reference(path, speed_profile(path, SpeedLimits()), WHEELBASE)


def test_horizon_shapes_and_first_point(reference: Reference) -> None:
    h = reference.horizon(12.3, 30, 0.05)
    for arr in (h.s, h.x, h.y, h.theta, h.v, h.delta):
        assert arr.shape == (31,)
    assert h.as_array().shape == (31, 5)
    assert h.s[0] == pytest.approx(12.3)
    np.testing.assert_allclose([h.x[0], h.y[0]], reference.path.position(12.3), atol=1e-4)
    assert h.v[0] == pytest.approx(reference.profile.speed(12.3), rel=1e-3)
    np.testing.assert_allclose(h.as_array()[:, 2], h.theta)


@pytest.mark.parametrize("s0", [0.0, 20.0, 47.0, 70.0])
def test_horizon_spacing_is_v_dt(reference: Reference, s0: float) -> None:
    dt = 0.04
    h = reference.horizon(s0, 40, dt)
    length = reference.path.length
    s_unwrapped = s0 + np.concatenate([[0.0], np.cumsum(np.mod(np.diff(h.s), length))])
    step = np.diff(s_unwrapped)
    expected = 0.5 * (h.v[:-1] + h.v[1:]) * dt
    np.testing.assert_allclose(step, expected, rtol=0.02, atol=1e-4)
    np.testing.assert_allclose(h.v, reference.profile.speed(h.s), rtol=1e-3)


def test_theta_continuous_across_start_line(reference: Reference) -> None:
    length = reference.path.length
    h = reference.horizon(length - 0.5, 30, 0.05)
    assert np.all(h.s >= 0.0) and np.all(h.s < length)
    assert np.any(h.s < 1.0) and np.any(h.s > length - 1.0)  # it did cross the line
    assert -np.pi < h.theta[0] <= np.pi
    assert np.max(np.abs(np.diff(h.theta))) < 0.1
    np.testing.assert_allclose(wrap_angle(h.theta - reference.path.heading(h.s)), 0.0, atol=1e-3)


def test_theta_continuous_over_a_full_lap(reference: Reference) -> None:
    dt = 0.1
    n = int(np.ceil(1.2 * reference.lap_time / dt))
    h = reference.horizon(5.0, n, dt)
    assert np.max(np.abs(np.diff(h.theta))) < 0.5
    # One counter-clockwise lap adds 2*pi to the heading.
    k = round(reference.lap_time / dt)
    assert h.theta[k] - h.theta[0] == pytest.approx(2 * np.pi, abs=0.1)
    assert h.s[k] == pytest.approx(5.0, abs=0.5)


def test_delta_is_kinematic_feed_forward(reference: Reference) -> None:
    h = reference.horizon(40.0, 30, 0.05)
    kappa = np.asarray(reference.path.curvature(h.s))
    np.testing.assert_allclose(h.delta, np.arctan(WHEELBASE * kappa), atol=2e-3)


def test_project_delegates(reference: Reference) -> None:
    p = reference.project(*reference.path.position(3.0), s_hint=2.9)
    assert p.s == pytest.approx(3.0, abs=1e-4)
    assert p.lateral == pytest.approx(0.0, abs=1e-6)


def test_bad_arguments(reference: Reference) -> None:
    with pytest.raises(ParameterError):
        Reference(reference.path, reference.profile, 0.0)
    other = builtin_track("oval").centerline
    with pytest.raises(ParameterError):
        Reference(other, reference.profile, WHEELBASE)
    with pytest.raises(ParameterError):
        reference.horizon(0.0, 10, 0.0)
