"""Tests of rkmpc.track.reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
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


# ---------------------------------------------------------------- fast path == plain implementation
def plain_horizon(ref: Reference, s0: float, n_steps: int, dt: float) -> np.ndarray:
    """The straightforward horizon (the code before the fast path), rows s, x, y, theta, v, delta."""
    length = ref.path.length
    lap_time = ref.lap_time
    s0w = s0 % length
    t0 = float(np.interp(s0w, ref._s_prof, ref._t_prof))
    t = t0 + dt * np.arange(n_steps + 1)
    laps = np.floor(t / lap_time)
    s_lap = np.interp(t - laps * lap_time, ref._t_prof, ref._s_prof)
    s_lap[0] = s0w
    u = s_lap / ref._ds
    idx = np.minimum(u.astype(np.intp), ref._n_tab - 1)
    frac = (u - idx)[:, None]
    tab = ref._table
    vals = tab[idx] * (1.0 - frac) + tab[idx + 1] * frac
    theta = vals[:, 2] + 2 * np.pi * ref.path.winding_number * laps
    th0 = theta[0]
    wrapped0 = math.pi - math.fmod(math.pi - th0, 2 * math.pi)
    if wrapped0 <= -math.pi:
        wrapped0 += 2 * math.pi
    elif wrapped0 > math.pi:
        wrapped0 -= 2 * math.pi
    theta = theta + (wrapped0 - th0)
    s_out = np.where(s_lap >= length, s_lap - length, s_lap)
    return np.array([s_out, vals[:, 0], vals[:, 1], theta, vals[:, 3], vals[:, 4]])


def horizon_rows(ref: Reference, s0: float, n_steps: int, dt: float) -> np.ndarray:
    h = ref.horizon(s0, n_steps, dt)
    return np.array([h.s, h.x, h.y, h.theta, h.v, h.delta])


def assert_same(fast: np.ndarray, plain: np.ndarray) -> None:
    """Equal to floating-point noise: 1e-12 relative to each row's scale."""
    for a, b in zip(fast, plain, strict=True):
        scale = max(1.0, float(np.max(np.abs(b))))
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * scale)


def start_points(ref: Reference, rng: np.random.Generator) -> np.ndarray:
    length = ref.path.length
    return np.concatenate(
        [
            rng.uniform(0.0, length, 300),
            length - rng.uniform(0.0, 3.0, 50),  # horizons across the start line
            rng.uniform(-3.0, 3.0, 30),  # negative starts wrap
            rng.uniform(0.0, length, 10) + length * rng.integers(-3, 4, 10),
            [0.0, length, -0.0, 1e-300, -1e-300, length - 1e-12, np.nextafter(length, 0.0)],
        ]
    )


@pytest.mark.parametrize("n_steps, dt", [(30, 0.05), (0, 0.05), (7, 0.2), (30, 0.1)])
def test_horizon_fast_path_matches_plain(reference: Reference, n_steps: int, dt: float) -> None:
    rng = np.random.default_rng(n_steps)
    for s0 in start_points(reference, rng):
        assert_same(horizon_rows(reference, s0, n_steps, dt), plain_horizon(reference, s0, n_steps, dt))
    # A horizon longer than a lap, and numpy scalars as input.
    assert_same(horizon_rows(reference, np.float64(3.0), 400, 0.1), plain_horizon(reference, 3.0, 400, 0.1))


def test_horizon_fast_path_matches_plain_on_a_long_track(shared_tracks) -> None:
    from rkmpc.sim.scenario import load_scenario

    ref = load_scenario(str(shared_tracks / "centerlines" / "Monza.csv")).reference
    rng = np.random.default_rng(1)
    for s0 in start_points(ref, rng):
        assert_same(horizon_rows(ref, s0, 30, 0.05), plain_horizon(ref, s0, 30, 0.05))


def test_horizon_results_are_fresh_arrays(reference: Reference) -> None:
    a = reference.horizon(10.0, 30, 0.05)
    kept = a.as_array().copy()
    reference.horizon(50.0, 30, 0.05)
    np.testing.assert_array_equal(a.as_array(), kept)
    assert a == a and isinstance(a, type(reference.horizon(1.0, 3, 0.05)))


def test_reference_survives_pickling(reference: Reference) -> None:
    import pickle

    reference.horizon(10.0, 30, 0.05)
    copy = pickle.loads(pickle.dumps(reference))
    assert_same(horizon_rows(copy, 10.0, 30, 0.05), horizon_rows(reference, 10.0, 30, 0.05))
    p = copy.project(1.0, 2.0, s_hint=0.5)
    assert p == reference.project(1.0, 2.0, s_hint=0.5)


def test_horizon_from_threads(reference: Reference) -> None:
    from concurrent.futures import ThreadPoolExecutor

    starts = np.linspace(0.0, 2 * reference.path.length, 400)
    expected = [plain_horizon(reference, s0, 30, 0.05) for s0 in starts]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda s0: horizon_rows(reference, s0, 30, 0.05), starts))
    for a, b in zip(got, expected, strict=True):
        assert_same(a, b)


@pytest.mark.parametrize("s0", [3.0, 47.0])
def test_along_matches_horizon_at_its_arc_lengths(reference: Reference, s0: float) -> None:
    """``along`` at the distances the time-indexed horizon covers gives the horizon's points."""
    h = reference.horizon(s0, 40, 0.05)
    length = reference.path.length
    distances = np.cumsum(np.mod(np.diff(h.s), length))
    a = reference.along(s0, distances)
    np.testing.assert_allclose(a.s, h.s, atol=1e-9)
    for name in ("x", "y", "theta", "v", "delta"):
        np.testing.assert_allclose(getattr(a, name), getattr(h, name), atol=1e-9, err_msg=name)


def test_along_places_points_at_any_distance_and_across_the_start_line(reference: Reference) -> None:
    length = reference.path.length
    s0 = length - 0.3
    distances = np.array([0.0, 0.1, 0.25, 0.6, 1.5, 1.5, 4.0])
    a = reference.along(s0 + 2.0 * length, distances)  # s0 any real: wrapped
    expected_s = np.mod(s0 + np.concatenate([[0.0], distances]), length)
    np.testing.assert_allclose(a.s, expected_s, atol=1e-9)
    assert np.all(a.s >= 0.0) and np.all(a.s < length)
    np.testing.assert_allclose(np.column_stack([a.x, a.y]), reference.path.position(a.s), atol=1e-4)
    assert -np.pi < a.theta[0] <= np.pi
    assert np.max(np.abs(np.diff(a.theta))) < 0.5  # continuous across the line
    np.testing.assert_allclose(wrap_angle(a.theta - reference.path.heading(a.s)), 0.0, atol=1e-3)
    np.testing.assert_allclose(a.v, reference.profile.speed(a.s), rtol=1e-3)
    assert a.theta[5] == a.theta[6]  # the same distance twice: the same point
