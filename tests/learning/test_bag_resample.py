"""Resampling time-stamped odometry and commands onto the control period (no bag, no rosbags)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.learning.data.bags.config import BagImportConfig, BagWriteConfig
from rkmpc.learning.data.bags.read import ODOM_FIELDS, Stream
from rkmpc.learning.data.bags.resample import odometry_at_cog, resample, transitions

MS = 1_000_000  # ns


def _odom(t_ms: np.ndarray, speed: float = 1.0) -> Stream:
    """A car driving straight along x at ``speed`` (m/s), odometry at the given instants (ms)."""
    t = t_ms / 1000.0
    values = np.stack([speed * t, 0 * t, 0 * t, np.full_like(t, speed), 0 * t, 0 * t], axis=1)
    return Stream("/odom", (t_ms * MS).astype(np.int64), values, ODOM_FIELDS)


def _drive(t_ms: np.ndarray, values: np.ndarray) -> Stream:
    return Stream(
        "/drive", (np.asarray(t_ms) * MS).astype(np.int64), np.asarray(values, float), ("speed", "steer")
    )


def _resample(odom: Stream, drive: Stream, tolerance: float = 0.0125, gap: float = 0.15):
    return resample(odom, drive, None, dt=0.05, gap=gap, tolerance=tolerance)


def test_each_sample_holds_the_last_command_within_the_timer_jitter():
    """Commands every 50 ms, alternately 2 ms late and early: a quarter-period tolerance absorbs it."""
    odom = _odom(np.arange(0, 3001, 10.0))
    k = np.arange(40)
    jitter = np.where(k % 2 == 1, 2.0, -2.0)
    jitter[0] = 0.0
    drive = _drive(100 + 50 * k + jitter, np.stack([k, 0.01 * k], axis=1))
    held = _resample(odom, drive)
    # The grid starts at the first command (100 ms): no sample before it.
    assert held.stamps[0] == 100 * MS and np.all(np.diff(held.stamps) == 50 * MS)
    np.testing.assert_array_equal(held.command[:40, 0], k)
    np.testing.assert_allclose(held.obs[:, 0], held.stamps / 1e9, atol=1e-12)  # x = t, interpolated
    strict = _resample(odom, drive, tolerance=0.0)
    late = k % 2 == 1
    np.testing.assert_array_equal(strict.command[:40, 0][late], k[late] - 1)
    np.testing.assert_array_equal(strict.command[:40, 0][~late], k[~late])


def test_a_stale_command_and_a_reversing_car_make_holes():
    odom = _odom(np.arange(0, 3001, 10.0))
    drive = _drive([0, 50, 100, 1000, 1050], [[1, 0]] * 5)  # nothing from 100 to 1000 ms
    samples = _resample(odom, drive)
    stale = (samples.stamps > 250 * MS) & (samples.stamps < 1000 * MS)
    assert not samples.usable[stale].any() and samples.usable[~stale][:5].all()
    found = transitions(samples)
    # Samples 0-250 ms and 1000-1200 ms: a command is held for at most the gap, 150 ms.
    assert np.bincount(found.episode).tolist() == [5, 4]
    backwards = _resample(_odom(np.arange(0, 1001, 10.0), speed=-0.2), _drive([0], [[0, 0]]), gap=10.0)
    assert len(transitions(backwards)) == 0


def test_samples_lie_inside_odometry_stretches_only():
    odom = _odom(np.concatenate([np.arange(0, 501, 10.0), np.arange(1000, 1501, 10.0)]))
    samples = _resample(odom, _drive(np.arange(-30, 1500, 50.0), np.ones((31, 2))))
    assert samples.stamps[0] == 20 * MS  # first grid point (-30 + k 50 ms) inside the odometry
    assert not np.any((samples.stamps > 500 * MS) & (samples.stamps < 1000 * MS))
    assert np.bincount(transitions(samples).episode).tolist() == [9, 9]


def test_the_rear_axle_lies_lr_behind_the_centre_of_gravity():
    lr = 0.145
    rear = np.array([[1.0, 2.0, math.pi / 2, 3.0, 0.1, 2.0]])
    cog = odometry_at_cog(rear, lr)
    np.testing.assert_allclose(cog, [[1.0, 2.0 + lr, math.pi / 2, 3.0, 0.1 + lr * 2.0, 2.0]], atol=1e-15)
    np.testing.assert_allclose(odometry_at_cog(cog, -lr), rear, atol=1e-15)


def test_slip_is_undefined_below_the_slip_speed():
    odom = _odom(np.arange(0, 1001, 10.0), speed=0.3)
    slow = resample(odom, _drive([0], [[0.3, 0]]), None, dt=0.05, gap=10.0, tolerance=0.0)
    assert np.all(np.isnan(slow.obs[:, 5]))
    fine = resample(odom, _drive([0], [[0.3, 0]]), None, dt=0.05, gap=10.0, tolerance=0.0, min_slip_speed=0.2)
    np.testing.assert_array_equal(fine.obs[:, 5], 0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dt": 0.0}, "dt"),
        ({"odom_topic": ""}, "odom_topic"),
        ({"drive_topic": "/ego_racecar/odom"}, "must differ"),
        ({"steer_gain": 0.0}, "steer_gain"),
        ({"odom_frame": "base_link"}, "odom_frame"),
        ({"stamps": "wall"}, "stamps"),
        ({"max_gap": -1.0}, "max_gap"),
        ({"command_tolerance": 0.05}, "command_tolerance"),
        ({"min_samples": 0}, "min_samples"),
        ({"min_slip_speed": math.nan}, "min_slip_speed"),
    ],
)
def test_import_options_are_validated(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        BagImportConfig(**kwargs)


def test_defaults_follow_the_f1tenth_simulator():
    config = BagImportConfig()
    assert (config.odom_topic, config.drive_topic, config.odom_frame) == (
        "/ego_racecar/odom",
        "/drive",
        "cog",
    )
    assert config.gap == pytest.approx(0.15) and config.tolerance == pytest.approx(0.0125)
    assert BagWriteConfig().storage == "mcap"
    with pytest.raises(ParameterError, match="storage"):
        BagWriteConfig(storage="rosbag3")
