"""Tests of rkmpc.track.path."""

from __future__ import annotations

import numpy as np
import pytest

from projection_reference import project_plain
from rkmpc.core.errors import ParameterError
from rkmpc.track import Path, wrap_angle


def circle(radius: float, n: int = 100, clockwise: bool = False) -> Path:
    th = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    if clockwise:
        th = -th
    return Path.from_points(np.column_stack([radius * np.cos(th), radius * np.sin(th)]))


@pytest.mark.parametrize("radius", [0.8, 5.0, 120.0])
def test_circle_arc_length_heading_curvature(radius: float) -> None:
    path = circle(radius)
    assert path.length == pytest.approx(2 * np.pi * radius, rel=1e-5)
    assert path.speed_error() < 1e-3
    s = np.linspace(0.0, path.length, 500, endpoint=False)
    pos = path.position(s)
    np.testing.assert_allclose(np.hypot(pos[:, 0], pos[:, 1]), radius, rtol=1e-4)
    # Arc length really is arc length: the polar angle advances by s / R.
    angle = np.unwrap(np.arctan2(pos[:, 1], pos[:, 0]))
    np.testing.assert_allclose(angle - angle[0], s / radius, atol=1e-4)
    np.testing.assert_allclose(path.curvature(s), 1.0 / radius, rtol=1e-3)
    expected_heading = wrap_angle(angle + np.pi / 2)
    np.testing.assert_allclose(wrap_angle(path.heading(s) - expected_heading), 0.0, atol=1e-4)
    assert path.winding_number == 1


def test_clockwise_circle_has_negative_curvature() -> None:
    path = circle(3.0, clockwise=True)
    s = np.linspace(0.0, path.length, 100, endpoint=False)
    np.testing.assert_allclose(path.curvature(s), -1.0 / 3.0, rtol=1e-3)
    assert path.winding_number == -1


def test_heading_range_and_unwrapped_continuity() -> None:
    path = circle(2.0)
    s = np.linspace(-path.length, 2 * path.length, 3001)
    h = np.asarray(path.heading(s))
    assert np.all(h > -np.pi) and np.all(h <= np.pi)
    hu = np.asarray(path.heading_unwrapped(s))
    assert np.max(np.abs(np.diff(hu))) < 0.02
    np.testing.assert_allclose(path.heading_unwrapped(s[:100] + path.length), hu[:100] + 2 * np.pi, atol=1e-9)
    np.testing.assert_allclose(wrap_angle(hu - h), 0.0, atol=1e-9)


def test_position_wraps_modulo_length() -> None:
    path = circle(2.0)
    np.testing.assert_allclose(path.position(1.0 + 3 * path.length), path.position(1.0), atol=1e-9)
    np.testing.assert_allclose(path.position(-0.5), path.position(path.length - 0.5), atol=1e-9)


def test_sample_uniform_grid() -> None:
    path = circle(2.0)
    smp = path.sample(0.1)
    n = smp.s.size
    assert n == int(np.ceil(path.length / 0.1))
    np.testing.assert_allclose(np.diff(smp.s), path.length / n)
    assert smp.s[0] == 0.0 and smp.s[-1] < path.length
    assert smp.xy.shape == (n, 2)
    np.testing.assert_allclose(smp.curvature, 0.5, rtol=1e-3)


def test_duplicates_and_closing_point_dropped() -> None:
    th = np.linspace(0.0, 2 * np.pi, 50, endpoint=False)
    pts = np.column_stack([np.cos(th), np.sin(th)])
    with_dupes = np.vstack([pts[:10], pts[9:10], pts[10:], pts[:1]])
    a = Path.from_points(pts)
    b = Path.from_points(with_dupes)
    assert a.length == pytest.approx(b.length, rel=1e-12)


def test_bad_points_raise() -> None:
    with pytest.raises(ParameterError):
        Path.from_points(np.zeros((3, 2)) + np.arange(3)[:, None])
    with pytest.raises(ParameterError):
        Path.from_points(np.ones((10, 3)))
    bad = np.column_stack([np.cos(np.arange(10.0)), np.sin(np.arange(10.0))])
    bad[3, 0] = np.nan
    with pytest.raises(ParameterError):
        Path.from_points(bad)


def offset_points(path: Path, s: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    pos = path.position(s)
    h = np.asarray(path.heading(s))
    return pos + lateral[:, None] * np.column_stack([-np.sin(h), np.cos(h)])


def s_error(path: Path, a: float, b: float) -> float:
    d = (a - b) % path.length
    return min(d, path.length - d)


@pytest.mark.parametrize("hinted", [False, True])
def test_projection_of_offset_points(stadium: Path, hinted: bool) -> None:
    rng = np.random.default_rng(0)
    s = rng.uniform(0.0, stadium.length, 300)
    lat = rng.uniform(-0.4, 0.4, 300)
    pts = offset_points(stadium, s, lat)
    for k in range(s.size):
        hint = s[k] + 0.2 if hinted else None
        p = stadium.project(pts[k, 0], pts[k, 1], s_hint=hint)
        assert 0.0 <= p.s < stadium.length
        assert s_error(stadium, p.s, s[k]) < 2e-3
        assert p.lateral == pytest.approx(lat[k], abs=1e-4)
        assert abs(wrap_angle(p.heading - stadium.heading(s[k]))) < 1e-2


def test_projection_across_start_line(stadium: Path) -> None:
    length = stadium.length
    before = offset_points(stadium, np.array([length - 0.03]), np.array([0.2]))[0]
    after = offset_points(stadium, np.array([0.03]), np.array([0.2]))[0]
    for hint_b, hint_a in [(None, None), (0.01, length - 0.01), (length - 0.2, 0.2)]:
        pb = stadium.project(before[0], before[1], s_hint=hint_b)
        pa = stadium.project(after[0], after[1], s_hint=hint_a)
        assert pb.s == pytest.approx(length - 0.03, abs=1e-3)
        assert pa.s == pytest.approx(0.03, abs=1e-3)
        assert pb.lateral == pytest.approx(0.2, abs=1e-4)
        assert pa.lateral == pytest.approx(0.2, abs=1e-4)

    # A trajectory crossing the line: s wraps exactly once, lateral is continuous.
    s_traj = np.linspace(length - 2.0, length + 2.0, 81)
    lat = 0.1 * np.sin(s_traj)
    s_out, lat_out = stadium.project_many(offset_points(stadium, s_traj, lat))
    assert np.sum(np.diff(s_out) < 0) == 1
    np.testing.assert_allclose(lat_out, lat, atol=1e-4)
    np.testing.assert_allclose(np.unwrap(s_out, period=length), s_traj, atol=1e-3)
    _, lat_glob = stadium.project_many(offset_points(stadium, s_traj, lat), hinted=False)
    np.testing.assert_allclose(lat_glob, lat_out, atol=1e-9)


def test_hinted_projection_stays_on_its_straight(stadium: Path) -> None:
    # Bottom straight at y = 0 (heading +x), top straight at y = 1 (heading -x).
    # The point is nearer the top straight, but the hint says we are on the bottom one.
    x, y = 7.0, 0.55
    s_bottom = 2.0  # the path starts at x = 5 on the bottom straight
    hinted = stadium.project(x, y, s_hint=s_bottom)
    assert hinted.s == pytest.approx(s_bottom, abs=1e-3)
    assert hinted.lateral == pytest.approx(0.55, abs=1e-4)
    # Without a hint the nearest point (top straight) wins: this is what the hint prevents.
    free = stadium.project(x, y)
    assert s_error(stadium, free.s, s_bottom) > 5.0
    assert free.lateral == pytest.approx(0.45, abs=1e-4)
    # Even with a stale hint a few decimetres off, the search follows the path, not the gap.
    stale = stadium.project(x, y, s_hint=s_bottom - 1.5)
    assert stale.s == pytest.approx(s_bottom, abs=1e-3)


def test_explicit_window_must_be_positive(stadium: Path) -> None:
    with pytest.raises(ParameterError):
        stadium.project(0.0, 0.0, s_hint=0.0, window=0.0)


# ---------------------------------------------------------------- fast path == plain implementation
def random_queries(path: Path, rng: np.random.Generator, n: int) -> list[tuple[float, float, float]]:
    """Points near the path with hints near their arc length, many across s = 0, some far off."""
    length = path.length
    s = np.concatenate([rng.uniform(0.0, length, n), rng.uniform(-1.0, 1.0, n // 4) % length])
    lat = rng.uniform(-0.5, 0.5, s.size)
    lat[::10] *= 20.0  # far from the path: the window may have to move
    pts = offset_points(path, s, lat)
    hints = s + rng.uniform(-1.5, 1.5, s.size) + length * rng.integers(-2, 3, s.size)
    return [(float(px), float(py), float(h)) for (px, py), h in zip(pts, hints, strict=True)]


def assert_projection_matches(
    path: Path, queries: list[tuple[float, float, float]], window: float | None
) -> None:
    for x, y, hint in queries:
        p = path.project(x, y, s_hint=hint, window=window)
        e = project_plain(path, x, y, hint, window)
        np.testing.assert_allclose(
            [p.s, p.lateral, p.heading], [e.s, e.lateral, e.heading], rtol=1e-12, atol=1e-12
        )


@pytest.mark.parametrize("window", [None, 0.3, 1e3])
def test_hinted_projection_matches_plain(stadium: Path, window: float | None) -> None:
    assert_projection_matches(stadium, random_queries(stadium, np.random.default_rng(3), 400), window)


def test_hinted_projection_matches_plain_on_a_real_track(tracks_dir) -> None:
    from rkmpc.track import load_track

    path = load_track(tracks_dir / "centerlines" / "Monza.csv").centerline
    assert_projection_matches(path, random_queries(path, np.random.default_rng(4), 1000), None)


def test_projection_survives_pickling_and_threads(stadium: Path) -> None:
    import pickle
    from concurrent.futures import ThreadPoolExecutor

    queries = random_queries(stadium, np.random.default_rng(5), 200)
    copy = pickle.loads(pickle.dumps(stadium))
    expected = [project_plain(stadium, *q) for q in queries]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda q: copy.project(q[0], q[1], s_hint=q[2]), queries * 3))
    for p, e in zip(got, expected * 3, strict=True):
        np.testing.assert_allclose(
            [p.s, p.lateral, p.heading], [e.s, e.lateral, e.heading], rtol=1e-12, atol=1e-12
        )
