"""The CSV import on the real car's logs (``../shared/real/f1tenth-car``): data, defects, windows.

What the logs hold was checked by hand against the other sensors (see
:mod:`rkmpc.learning.data.logs.presets`); these tests hold the import and its report to it.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError
from rkmpc.learning.data.logs import FRICTION_MAPS, import_csv_log
from rkmpc.learning.data.quality import dataset_quality
from rkmpc.learning.data.window import TimeWindow
from rkmpc.vehicle.params import f1tenth


@pytest.fixture(scope="module")
def imported(real_logs):
    """Both runs imported with the preset, once."""
    return {run: import_csv_log(real_logs / run, f1tenth(), FRICTION_MAPS) for run in ("DS2", "DS3")}


@pytest.mark.parametrize(("run", "low", "high"), [("DS2", 2350, 2600), ("DS3", 2400, 2600)])
def test_both_runs_import_with_nan_wheel_and_slip_angles(imported, run, low, high):
    data = imported[run].data
    # DS2: 159 s with a 27.8 s and a 2 s hole and 4.8 s of reversing; DS3: 127 s, all usable.
    assert low <= len(data) <= high
    assert np.isnan(data.obs[:, 5:]).all() and np.isnan(data.next_obs[:, 5:]).all()
    assert np.isfinite(data.obs[:, :5]).all() and (data.obs[:, 3] >= 0).all()
    assert data.metadata["source"] == "csv" and data.metadata["csv_spec"]["name"] == "friction-maps"
    assert data.contract.vehicle == "f1tenth" and data.contract.dt == 0.05
    # The commands are the logged ones, not the wheel angle: the servo was never measured.
    assert np.abs(data.command[:, 1]).max() <= 0.34 + 1e-6


def test_gaps_split_the_episodes_where_the_report_says(imported):
    report = imported["DS2"].report
    rates = {r.signal: r for r in report.rates}
    assert rates["pose"].longest_gap_s == pytest.approx(27.8, abs=0.05)
    assert [round(start) for start, _ in rates["pose"].gaps] == [115, 144, 153]
    assert 15 <= rates["pose"].p5_hz < rates["pose"].median_hz < rates["pose"].p95_hz <= 70
    starts = [e.start_s for e in report.episodes]
    assert len(report.episodes) >= 4 and starts == sorted(starts)
    # No episode runs across the 27.8 s hole (115.2 s to 143.0 s).
    assert not any(e.start_s < 115.2 < e.start_s + e.duration_s for e in report.episodes)
    assert sum(e.transitions for e in report.episodes) == report.transitions == len(imported["DS2"].data)


def test_pose_jumps_are_found_and_the_transitions_across_them_removed(imported):
    report = imported["DS2"].report
    big = max(report.jumps, key=lambda j: j.distance_m)
    assert big.distance_m == pytest.approx(0.84, abs=0.01) and big.time_s == pytest.approx(145.83, abs=0.01)
    assert len(report.jumps) >= 3 and report.jump_transitions >= len(report.jumps) - 1
    assert imported["DS3"].report.jumps == ()  # DS3's poses never jump by 0.3 m
    # What is left moves as its speed says: no transition jumps by the same rule.
    again = dataset_quality(imported["DS2"].data)
    assert max((j.distance_m for j in again.jumps), default=0.0) < 0.5


@pytest.mark.parametrize("run", ["DS2", "DS3"])
def test_the_speed_scale_of_each_run_is_measured(imported, run):
    fit = imported[run].report.speed_scale
    assert fit is not None and fit.windows > 1000
    # Over 0.5 s windows the VESC speed and the particle filter agree within a few per cent.
    assert 0.93 < fit.factor < 1.07 and fit.q25 < fit.factor < fit.q75 and not fit.warning


@pytest.mark.parametrize("run", ["DS2", "DS3"])
def test_the_imu_yaw_rate_is_found_in_deg_s_though_documented_as_rad_s(real_logs, imported, run):
    preset = {u.signal: u for u in imported[run].report.units}["yaw_rate"]
    assert preset.match == "deg/s" and not preset.suspicious
    as_documented = replace(FRICTION_MAPS, yaw_rate=replace(FRICTION_MAPS.yaw_rate, unit="rad/s"))
    report = import_csv_log(real_logs / run, f1tenth(), as_documented).report
    check = {u.signal: u for u in report.units}["yaw_rate"]
    assert check.suspicious and check.match == "deg/s" and check.correlation > 0.95
    assert check.raw_factor == pytest.approx(180 / math.pi, rel=0.08)
    assert "180/pi" in check.message and any("deg/s" in w for w in report.warnings)
    # The wrong unit does not turn every turn into a jump: the factor is divided out first.
    assert len(report.jumps) == len(imported[run].report.jumps)


@pytest.mark.parametrize(("run", "segments"), [("DS2", 3), ("DS3", 1)])
def test_reversing_is_counted_and_left_out(imported, run, segments):
    reversing = imported[run].report.reversing
    assert reversing is not None and reversing.segments == segments
    assert reversing.total_s > 0.5 and reversing.slowest_m_s < -1.0 and reversing.excluded_samples > 10


def test_columns_that_repeat_or_carry_nothing_are_named(imported):
    notes = imported["DS2"].report.columns
    assert ("odomData.csv", "wx repeats vx in every row") in notes
    assert any(f == "odomData.csv" and "wz" in n and "0 in every row" in n for f, n in notes)


def test_coverage_and_the_report_as_json_and_markdown(imported):
    report = imported["DS2"].report
    lo, hi = report.coverage.speed_range
    assert lo >= 0.0 and 4.5 < hi < 5.5
    assert sum(report.coverage.speed.counts) == report.transitions
    assert report.coverage.curvature is not None and report.coverage.curvature_range is not None
    text = report.to_markdown()
    assert max(len(line) for line in text.splitlines()) <= 100
    assert "deg/s" in text and "145.83" in text
    record = json.loads(json.dumps(report.to_json()))
    assert record["transitions"] == report.transitions and record["rates"][0]["longest_gap_s"] > 27


def test_a_window_keeps_its_span_relative_or_absolute(real_logs, imported):
    full = imported["DS3"]
    part = import_csv_log(real_logs / "DS3", f1tenth(), FRICTION_MAPS, window=TimeWindow(10.0, 60.0))
    spans = part.report.episodes
    assert spans[0].start_s >= 10.0 and spans[-1].start_s + spans[-1].duration_s <= 60.0 + 1e-9
    assert 0.9 * 50 / 0.05 < len(part.data) <= 50 / 0.05
    assert part.report.window == "10:60" and part.data.metadata["window"]["start"] == 10.0
    # The same transitions as the full import over that span: the grid is the same.
    gaps = np.hypot(*(full.data.obs[None, :, :2] - part.data.obs[:, None, :2]).transpose(2, 0, 1))
    rows = np.argmin(gaps, axis=1)
    np.testing.assert_allclose(full.data.obs[rows], part.data.obs, atol=1e-9)
    np.testing.assert_array_equal(np.diff(rows)[np.diff(part.data.episode) == 0], 1)
    start = full.data.metadata["start_stamp"]
    absolute = TimeWindow(start + 10.0, start + 60.0, absolute=True)
    again = import_csv_log(real_logs / "DS3", f1tenth(), FRICTION_MAPS, window=absolute)
    np.testing.assert_array_equal(again.data.obs, part.data.obs)


def test_a_window_outside_the_log_is_an_error_naming_it(real_logs):
    with pytest.raises(InputFileError, match=r"window 500:600 holds 0 sample\(s\) of pose .*spans 0 to 127"):
        import_csv_log(real_logs / "DS3", f1tenth(), FRICTION_MAPS, window=TimeWindow(500.0, 600.0))


@pytest.mark.parametrize("run", ["DS2", "DS3"])
def test_the_pose_moves_like_the_centre_of_gravity_the_preset_takes_it_for(imported, run):
    # The logger's notes do not say which point the pose is of; how it moves sideways in turns does.
    point = imported[run].report.pose_point
    assert point is not None and point.consistent is True
    assert point.expected_m == f1tenth().lr
    assert abs(point.offset_m - point.expected_m) < 3 * point.std_error_m < 0.05
    assert point.samples > 1500
    assert not any("which point of the car" in w for w in imported[run].report.warnings)
    assert "Where the pose is on the car" in imported[run].report.to_markdown()


def test_a_pose_frame_set_wrongly_is_a_warning(real_logs):
    # Taken for the rear axle, the pose is moved lr forward: it then moves like a point 2 lr ahead.
    wrong = replace(FRICTION_MAPS, pose=replace(FRICTION_MAPS.pose, frame="rear-axle"))
    report = import_csv_log(real_logs / "DS2", f1tenth(), wrong).report
    point = report.pose_point
    assert point is not None and point.consistent is False
    assert point.offset_m == pytest.approx(2 * f1tenth().lr, abs=3 * point.std_error_m)
    assert any("check which point of the car the pose is of" in w for w in report.warnings)
    assert "NOT consistent" in report.to_markdown()
