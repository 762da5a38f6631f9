"""Tests of rkmpc.track.builtin."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.track import (
    BUILTIN_DESCRIPTIONS,
    Track,
    builtin_track,
    find_self_intersection,
    list_builtin_tracks,
)

F1TENTH_MIN_RADIUS = 0.307 / np.tan(0.4189)  # ~0.69 m


@pytest.fixture(scope="module")
def track() -> Track:
    return builtin_track()


def longest_run(mask: np.ndarray) -> int:
    """Longest run of True in a periodic boolean array."""
    if mask.all():
        return mask.size
    m = np.roll(mask, -int(np.argmin(mask)))
    best = run = 0
    for v in m:
        run = run + 1 if v else 0
        best = max(best, run)
    return best


def test_names_and_descriptions() -> None:
    names = list_builtin_tracks()
    assert "builtin" in names and "oval" in names
    assert set(BUILTIN_DESCRIPTIONS) == set(names)
    with pytest.raises(ValueError, match="builtin"):
        builtin_track("nope")


@pytest.mark.parametrize("name", list_builtin_tracks())
def test_closed_simple_smooth(name: str) -> None:
    tr = builtin_track(name)
    assert tr.name == name
    assert 50.0 <= tr.length <= 150.0
    smp = tr.centerline.sample(0.02)
    assert find_self_intersection(smp.xy) is None
    left, right = tr.boundaries(0.05)
    assert find_self_intersection(left) is None
    assert find_self_intersection(right) is None
    # Closed: the path comes back to its start smoothly (no kink at s = 0).
    gaps = np.hypot(*np.diff(np.vstack([smp.xy, smp.xy[:1]]), axis=0).T)
    assert gaps.max() < 0.021
    assert np.max(np.abs(np.diff(np.append(smp.curvature, smp.curvature[0])))) < 0.05
    # Drivable by an F1TENTH car with margin; widths between 0.5 and 1 m.
    assert np.max(np.abs(smp.curvature)) <= 1.0 / 1.2
    assert 1.0 / np.max(np.abs(smp.curvature)) > 1.5 * F1TENTH_MIN_RADIUS
    for w in (tr.width_left(smp.s), tr.width_right(smp.s)):
        assert np.all((np.asarray(w) >= 0.5) & (np.asarray(w) <= 1.0))
    assert abs(tr.centerline.winding_number) == 1


def test_features(track: Track) -> None:
    ds = 0.05
    smp = track.centerline.sample(ds)
    k = smp.curvature
    # Straight: |kappa| < 0.02 for more than 5 m, and s = 0 lies on one.
    straight = np.abs(k) < 0.02
    assert longest_run(straight) * ds > 5.0
    assert np.all(np.abs(track.centerline.curvature(np.linspace(-1.0, 1.0, 41))) < 0.02)
    # Hairpin: heading changes by more than 2.5 rad within 8 m.
    hu = np.asarray(track.centerline.heading_unwrapped(np.arange(0.0, 2 * track.length, ds)))
    n8 = int(8.0 / ds)
    assert np.max(np.abs(hu[n8:] - hu[:-n8])) > 2.5
    # Chicane: two sign changes of clearly non-zero curvature within 8 m.
    strong = np.flatnonzero(np.abs(k) > 0.2)
    signs = np.sign(k[strong])
    change = strong[1:][signs[1:] != signs[:-1]] * ds
    assert np.any(np.diff(change) < 8.0)


def test_oval_has_no_chicane() -> None:
    k = builtin_track("oval").centerline.sample(0.05).curvature
    assert np.all(k > -0.02)
