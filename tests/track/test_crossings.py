"""Tracks that cross themselves: bridges accepted, folds refused, projections stay on their pass."""

from __future__ import annotations

import math
from pathlib import Path as FilePath

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.track import Path, Track, find_self_intersection, load_centerline, load_track
from rkmpc.track.crossings import (
    BRIDGE_MIN_ANGLE,
    bridge_problem,
    min_bridge_separation,
    path_crossings,
    segment_crossings,
)

HEADER = "x_m,y_m,w_tr_right_m,w_tr_left_m"


def write_centerline(path: FilePath, xy: np.ndarray, half_width: float) -> FilePath:
    rows = np.column_stack([xy, np.full(len(xy), half_width), np.full(len(xy), half_width)])
    np.savetxt(path, rows, delimiter=",", header=HEADER, fmt="%.6f")
    return path


def keyhole(gap: float = 0.05, step: float = 2.0, spike: float = 10.0, radius: float = 10.0) -> np.ndarray:
    """A circle with a narrow hairpin spike (two legs ``gap`` apart, points ``step`` apart) at its right."""
    h = gap / 2
    a0 = math.asin(h / radius)
    out = [(x, -h) for x in np.arange(radius * math.cos(a0), radius + spike + 1e-9, step)]
    out += [(x, h) for x in np.arange(radius + spike, radius * math.cos(a0) - 1e-9, -step)]
    out += [(radius * math.cos(a), radius * math.sin(a)) for a in np.linspace(a0, 2 * np.pi - a0, 40)[1:-1]]
    return np.array(out)


def test_the_rule_needs_distance_along_the_lap_and_an_angle() -> None:
    # Ten widths, a tenth of the lap, twice the projection window: the largest counts.
    assert min_bridge_separation(100.0, 2.0) == 20.0
    assert min_bridge_separation(400.0, 2.0) == 40.0
    assert min_bridge_separation(100.0, 0.5, window=15.0) == 30.0
    assert bridge_problem(50.0, math.radians(80), 100.0, 2.0) is None
    near = bridge_problem(15.0, math.radians(80), 100.0, 2.0)
    assert near is not None and "folds back" in near and "15 m apart" in near
    shallow = bridge_problem(50.0, 0.5 * BRIDGE_MIN_ANGLE, 100.0, 2.0)
    assert shallow is not None and "degrees" in shallow


def test_a_figure_eight_loads_with_its_bridge(figure_eight_csv: FilePath) -> None:
    track = load_track(figure_eight_csv, scale=1.0)
    (bridge,) = track.crossings
    assert math.hypot(bridge.x, bridge.y) < 0.01  # at the origin
    assert math.degrees(bridge.angle) == pytest.approx(77.3, abs=1.0)
    assert 0.0 <= bridge.s_first < bridge.s_second < track.length
    apart = bridge.s_second - bridge.s_first
    assert bridge.separation == pytest.approx(min(apart, track.length - apart))
    assert bridge.separation > 40.0
    for s in (bridge.s_first, bridge.s_second):
        assert np.linalg.norm(track.centerline.position(s)) < 0.01
    # A copy with a race line keeps them.
    assert track.with_raceline(track.centerline).crossings == track.crossings


def test_a_track_built_in_code_records_its_bridge_and_refuses_a_fold() -> None:
    t = np.linspace(0.0, 2 * np.pi, 200, endpoint=False) + 0.3
    eight = Track("eight", Path.from_points(np.column_stack([15 * np.sin(t), 6 * np.sin(2 * t)])), 1.2, 1.2)
    assert len(eight.crossings) == 1
    th = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    xy = np.column_stack([10 * np.cos(th), 10 * np.sin(th)])
    xy[[20, 21]] = xy[[21, 20]]
    with pytest.raises(ParameterError, match=r"'zigzag': the centre line crosses itself .* no bridge"):
        Track("zigzag", Path.from_points(xy), 0.5, 0.5)


def test_a_zig_zag_folding_back_is_refused_naming_its_lines(tmp_path: FilePath) -> None:
    th = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    xy = np.column_stack([10 * np.cos(th), 10 * np.sin(th)])
    xy[[20, 21]] = xy[[21, 20]]  # two points swapped: the line goes back and forth (a Z)
    path = write_centerline(tmp_path / "zigzag.csv", xy, 0.5)
    with pytest.raises(InputFileError) as info:
        load_centerline(path)
    message = str(info.value)
    assert "zigzag.csv" in message and "self-intersecting" in message and "folds back" in message
    assert "line 21" in message and "line 23" in message  # the two crossing segments (header is line 1)


def test_a_spline_crossing_itself_where_its_points_do_not_is_refused(tmp_path: FilePath) -> None:
    xy = keyhole()
    assert find_self_intersection(xy) is None  # the polyline is simple
    assert path_crossings(Path.from_points(xy))  # its spline is not
    path = write_centerline(tmp_path / "keyhole.csv", xy, 0.01)
    with pytest.raises(InputFileError) as info:
        load_centerline(path)
    message = str(info.value)
    assert "keyhole.csv" in message and "smoothed line" in message
    assert "s = " in message and "near lines" in message
    # The same points 0.5 m apart make a spline that stays simple: accepted.
    track = load_centerline(write_centerline(tmp_path / "dense.csv", keyhole(gap=0.2, step=0.5), 0.01))
    assert track.crossings == ()


def test_segment_crossings_finds_every_crossing_with_its_place() -> None:
    bowtie = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    (hit,) = segment_crossings(bowtie)
    assert (hit.i, hit.j) == (0, 2)
    assert (hit.x, hit.y) == pytest.approx((0.5, 0.5))
    assert (hit.t_i, hit.t_j) == pytest.approx((0.5, 0.5))
    assert hit.sin_angle == pytest.approx(1.0)
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert segment_crossings(square) == []


@pytest.mark.parametrize("offset", [-1.0, 0.0, 0.9])
def test_projections_stay_on_their_pass_through_the_crossing(
    figure_eight_csv: FilePath, offset: float
) -> None:
    from rkmpc.sim.scenario import load_scenario

    scenario = load_scenario(figure_eight_csv, scale=1.0)
    track, reference = scenario.track, scenario.reference
    line = track.centerline
    (bridge,) = track.crossings
    for s_pass in (bridge.s_first, bridge.s_second):
        s_true = np.arange(s_pass - 6.0, s_pass + 6.0, 0.05)
        normal = np.column_stack([-np.sin(line.heading(s_true)), np.cos(line.heading(s_true))])
        xy = line.position(s_true) + offset * normal
        hints = {"path": s_true[0], "reference": s_true[0], "track": s_true[0]}
        for s, (x, y) in zip(s_true, xy, strict=True):
            p = line.project(x, y, s_hint=hints["path"])
            r = reference.project(x, y, s_hint=hints["reference"])
            s_center, lateral, margin = track.boundary_offsets(x, y, hints["track"])
            for got in (p.s, r.s, s_center):
                assert abs((got - s + 0.5 * line.length) % line.length - 0.5 * line.length) < 1e-3
            assert p.lateral == pytest.approx(offset, abs=1e-3)
            assert lateral == pytest.approx(offset, abs=1e-3)
            assert margin == pytest.approx(1.2 - abs(offset), abs=1e-3)
            hints = {"path": p.s, "reference": r.s, "track": s_center}
        # The reference's horizon from the pass runs on along the same pass.
        horizon = reference.horizon(s_pass - 1.0, 20, 0.05)
        expected = line.position(horizon.s)
        assert np.allclose(np.column_stack([horizon.x, horizon.y]), expected, atol=1e-3)
