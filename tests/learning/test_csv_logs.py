"""The CSV import and its quality report on synthetic logs whose defects are known exactly."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from csv_logs import Drive
from rkmpc.learning.data.logs import FRICTION_MAPS, import_csv_log
from rkmpc.learning.data.quality import dataset_quality
from rkmpc.learning.data.window import TimeWindow
from rkmpc.vehicle.params import f1tenth


def test_a_clean_drive_is_one_episode_of_its_measured_values(drive_log):
    result = import_csv_log(drive_log(), f1tenth(), FRICTION_MAPS)
    data, report = result.data, result.report
    assert len(set(data.episode.tolist())) == 1 and 19.0 / 0.05 < len(data) < 20.0 / 0.05
    np.testing.assert_allclose(data.obs[:, 3], 2.0, atol=0.05)  # the speed sensor, resampled
    np.testing.assert_allclose(data.obs[:, 4], 0.5, atol=0.05)  # the IMU's deg/s in rad/s
    assert np.isnan(data.obs[:, 5:]).all()  # no slip, no wheel angle: never the command
    assert report.jumps == () and report.reversing is not None and report.reversing.segments == 0
    assert report.speed_scale is not None and report.speed_scale.factor == pytest.approx(1.0, abs=0.01)
    assert all(not u.suspicious for u in report.units)
    assert report.coverage.curvature_range == pytest.approx((0.25, 0.25), abs=0.03)
    assert report.warnings == ()


def test_the_report_finds_each_defect_put_in(drive_log):
    drive = Drive(speed_scale=1.2, gap=(5.0, 1.0), jump=(10.0, 0.8), reverse=(14.0, 2.0))
    result = import_csv_log(drive_log(drive), f1tenth(), FRICTION_MAPS)
    report = result.report
    rates = {r.signal: r for r in report.rates}
    assert [len(r.gaps) for r in report.rates] == [1, 1, 1, 1]
    assert rates["pose"].gaps[0][0] == pytest.approx(5.0, abs=0.05)
    assert rates["pose"].longest_gap_s == pytest.approx(1.0, abs=0.07)
    assert 30 < rates["pose"].median_hz < 50  # stamps every 18-32 ms
    (jump,) = report.jumps
    assert jump.time_s == pytest.approx(10.0, abs=0.04) and jump.distance_m == pytest.approx(0.8, abs=0.1)
    assert 1 <= report.jump_transitions <= 2
    fit = report.speed_scale
    assert fit is not None and fit.factor == pytest.approx(1.2, abs=0.01) and fit.warning
    reversing = report.reversing
    assert reversing is not None and reversing.segments == 1
    assert reversing.total_s == pytest.approx(2.0, abs=0.1) and 38 <= reversing.excluded_samples <= 41
    # Gap, jump and reversing each end an episode; nothing in the data reverses or jumps.
    assert len(report.episodes) == 4 and (result.data.obs[:, 3] > 0).all()
    assert dataset_quality(result.data).jumps == ()
    assert ("odomData.csv", "wx repeats vx in every row") in report.columns
    text = "\n".join(report.warnings)
    for needle in ("1 gap(s)", "1 pose jump(s)", "1.20", "times the speed", "1 reversing", "4 episodes"):
        assert needle in text


def test_a_yaw_rate_in_the_wrong_unit_is_named_with_its_factor(drive_log):
    folder = drive_log()
    in_rad = replace(FRICTION_MAPS, yaw_rate=replace(FRICTION_MAPS.yaw_rate, unit="rad/s"))
    report = import_csv_log(folder, f1tenth(), in_rad).report
    check = {u.signal: u for u in report.units}["yaw_rate"]
    assert check.suspicious and check.match == "deg/s" and check.declared_unit == "rad/s"
    assert check.raw_factor == pytest.approx(180 / math.pi, rel=0.02)
    assert "about 180/pi = 57.3" in check.message and check.message in report.warnings
    flipped = replace(FRICTION_MAPS, yaw_rate=replace(FRICTION_MAPS.yaw_rate, scale=-1.0))
    check = {u.signal: u for u in import_csv_log(folder, f1tenth(), flipped).report.units}["yaw_rate"]
    assert check.suspicious and check.match == "-deg/s" and "sign flipped" in check.message


def test_a_window_keeps_the_stretch_and_an_empty_one_is_refused(drive_log):
    folder = drive_log()
    result = import_csv_log(folder, f1tenth(), FRICTION_MAPS, window=TimeWindow.parse("5:10"))
    (episode,) = result.report.episodes
    assert episode.start_s >= 5.0 and episode.start_s + episode.duration_s <= 10.0 + 1e-9
    assert 95 <= len(result.data) <= 100 and result.report.span_s <= 5.0
    with pytest.raises(ValueError, match=r"window 30: holds 0 sample\(s\) of pose"):
        import_csv_log(folder, f1tenth(), FRICTION_MAPS, window=TimeWindow.parse("30:"))


def test_too_little_data_says_how_much_there_was(drive_log):
    spec = replace(FRICTION_MAPS, min_samples=500)
    with pytest.raises(ValueError, match=r"too little data: .* need at least 500"):
        import_csv_log(drive_log(), f1tenth(), spec)


def test_a_rear_axle_pose_is_moved_to_the_centre_of_gravity(drive_log):
    folder = drive_log()
    cog = import_csv_log(folder, f1tenth(), FRICTION_MAPS).data
    rear = replace(FRICTION_MAPS, pose=replace(FRICTION_MAPS.pose, frame="rear-axle"))
    moved = import_csv_log(folder, f1tenth(), rear).data
    shift = np.hypot(*(moved.obs[:, :2] - cog.obs[:, :2]).T)
    np.testing.assert_allclose(shift, f1tenth().lr, atol=1e-5)  # moved at the poses, then interpolated


def test_without_a_yaw_rate_it_is_nan_and_jumps_still_found(drive_log):
    folder = drive_log(Drive(jump=(10.0, 0.8)))
    result = import_csv_log(folder, f1tenth(), replace(FRICTION_MAPS, yaw_rate=None))
    assert np.isnan(result.data.obs[:, 4]).all() and len(result.report.jumps) == 1
    assert [u.signal for u in result.report.units] == ["speed"]
    assert result.report.coverage.curvature is None
