"""Tests of rkmpc.track.projection: the fast projection equals the plain reference implementation."""

from __future__ import annotations

import pickle
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from projection_reference import project_plain
from rkmpc.core.errors import ParameterError
from rkmpc.track import Path, Projection, builtin_track, load_track
from rkmpc.track.path import Projection as PathModuleProjection
from rkmpc.track.projection import PathProjector
from rkmpc.track.projection import Projection as ProjectionModuleProjection

Query = tuple[float, float, float]


@pytest.fixture(scope="module")
def builtin_path() -> Path:
    """Centre line of the built-in track (about 86 m)."""
    return builtin_track("builtin").centerline


@pytest.fixture(scope="module")
def monza(shared_tracks) -> Path:
    """Centre line of Monza at full size (about 5.8 km, 20000 table points)."""
    return load_track(shared_tracks / "centerlines" / "Monza.csv").centerline


def queries(path: Path, seed: int, n: int, *, near_start: bool = False) -> list[Query]:
    """``(x, y, hint)`` near the path, hints off by up to 2 m and whole laps; a few far off the path."""
    rng = np.random.default_rng(seed)
    length = path.length
    s = rng.uniform(-1.5, 1.5, n) % length if near_start else rng.uniform(0.0, length, n)
    lat = rng.uniform(-1.0, 1.0, n)
    lat[::8] *= 10.0  # far off: the window may have to move, the global search may jump
    h = np.asarray(path.heading(s))
    pts = path.position(s) + lat[:, None] * np.column_stack([-np.sin(h), np.cos(h)])
    hints = s + rng.uniform(-2.0, 2.0, n) + length * rng.integers(-2, 3, n)
    return [(float(x), float(y), float(hint)) for (x, y), hint in zip(pts, hints, strict=True)]


def as_tuple(p: Projection) -> tuple[float, float, float]:
    return (p.s, p.lateral, p.heading)


def assert_fast_equals_plain(path: Path, qs: list[Query], *, hinted: bool, window: float | None) -> None:
    """Fast and plain projections agree exactly (and certainly to 1e-12)."""
    for x, y, hint in qs:
        s_hint = hint if hinted else None
        fast = as_tuple(path.project(x, y, s_hint=s_hint, window=window))
        plain = as_tuple(project_plain(path, x, y, s_hint=s_hint, window=window))
        np.testing.assert_allclose(fast, plain, rtol=1e-12, atol=1e-12)
        assert fast == plain


@pytest.mark.parametrize(("hinted", "window"), [(False, None), (True, None), (True, 0.3), (True, 5.0)])
@pytest.mark.parametrize("near_start", [False, True])
def test_fast_equals_plain_on_the_builtin_track(
    builtin_path: Path, hinted: bool, window: float | None, near_start: bool
) -> None:
    qs = queries(builtin_path, 1, 300, near_start=near_start)
    assert_fast_equals_plain(builtin_path, qs, hinted=hinted, window=window)


@pytest.mark.parametrize(("hinted", "window"), [(False, None), (True, None), (True, 0.3), (True, 40.0)])
@pytest.mark.parametrize("near_start", [False, True])
def test_fast_equals_plain_on_a_real_track(
    monza: Path, hinted: bool, window: float | None, near_start: bool
) -> None:
    qs = queries(monza, 2, 300, near_start=near_start)
    assert_fast_equals_plain(monza, qs, hinted=hinted, window=window)


def test_fast_equals_plain_with_a_window_wider_than_the_padding(stadium: Path) -> None:
    # Wider than the padded table: the fast code falls back to its modular search.
    qs = queries(stadium, 3, 100, near_start=True)
    for window in (3.0 * stadium.default_window, 0.6 * stadium.length, 2.0 * stadium.length):
        assert_fast_equals_plain(stadium, qs, hinted=True, window=window)


def test_hinted_hot_path_equals_plain(builtin_path: Path, monza: Path) -> None:
    """The entry point of Reference.project (default window, no checks)."""
    for path in (builtin_path, monza):
        projector = path.projector
        for x, y, hint in queries(path, 4, 200, near_start=True):
            assert as_tuple(projector.project_hinted(x, y, hint)) == as_tuple(project_plain(path, x, y, hint))


@pytest.mark.parametrize("hinted", [False, True])
def test_project_many_equals_plain(builtin_path: Path, hinted: bool) -> None:
    # A trajectory over the start line twice (two laps and a bit).
    length = builtin_path.length
    s = np.linspace(length - 3.0, 2.0 * length + 3.0, 800)
    h = np.asarray(builtin_path.heading(s))
    xy = builtin_path.position(s) + (0.3 * np.sin(s))[:, None] * np.column_stack([-np.sin(h), np.cos(h)])
    s_out, lat_out = builtin_path.project_many(xy, hinted=hinted)
    hint: float | None = None
    for k, (x, y) in enumerate(xy.tolist()):
        p = project_plain(builtin_path, x, y, s_hint=hint)
        assert (s_out[k], lat_out[k]) == (p.s, p.lateral)
        hint = p.s if hinted else None
    assert np.sum(np.diff(s_out) < 0) == 2  # s wraps at each crossing of the start line


def test_plain_accepts_a_projector_and_checks_the_window(stadium: Path) -> None:
    x, y, hint = queries(stadium, 5, 1)[0]
    assert project_plain(stadium.projector, x, y, hint) == project_plain(stadium, x, y, hint)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ParameterError):
            project_plain(stadium, x, y, s_hint=hint, window=bad)
        with pytest.raises(ParameterError):
            stadium.project(x, y, s_hint=hint, window=bad)


def test_projection_is_exported_everywhere() -> None:
    assert Projection is PathModuleProjection is ProjectionModuleProjection
    with pytest.raises(ParameterError):
        PathProjector(
            np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), ds=1.0, length=3.0, default_window=1.0
        )


def test_pickled_path_projects_from_several_threads(stadium: Path) -> None:
    qs = queries(stadium, 6, 150, near_start=True)
    windows = (None, 0.3)
    stadium.project(*qs[0])  # fills this thread's scratch buffers, which must not be pickled
    copy = pickle.loads(pickle.dumps(stadium))
    assert copy.projector is not stadium.projector
    assert copy.projector._buffers == {}
    assert copy.default_window == stadium.default_window
    expected = {w: [as_tuple(project_plain(stadium, *q, window=w)) for q in qs] for w in windows}
    barrier = threading.Barrier(4)

    def work(w: float | None) -> tuple[int, list[tuple[float, float, float]]]:
        barrier.wait()  # all threads search at the same time
        out = []
        for _ in range(3):
            out.extend(as_tuple(copy.project(x, y, s_hint=hint, window=w)) for x, y, hint in qs)
        return threading.get_ident(), out

    jobs = [None, 0.3, None, 0.3]
    with ThreadPoolExecutor(len(jobs)) as pool:
        results = list(pool.map(work, jobs))
    for w, (_, got) in zip(jobs, results, strict=True):
        assert got == expected[w] * 3
    # The copy's scratch buffers: one set per (thread, half-width), none of this thread.
    workers = {ident for ident, _ in results}
    assert len(workers) == len(jobs)
    assert {key[0] for key in copy.projector._buffers} == workers
