"""Data-quality measures and the report of any data set, on data with known defects."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.quality import dataset_quality
from rkmpc.learning.data.quality import measures as m


def _circle(n: int = 400, dt: float = 0.05, speed: float = 2.0, rate: float = 0.5) -> np.ndarray:
    """Observations of a circle, ``n + 1`` samples."""
    t = dt * np.arange(n + 1)
    yaw = rate * t
    radius = speed / rate
    obs = np.full((n + 1, 7), math.nan)
    obs[:, 0], obs[:, 1] = radius * np.sin(yaw), radius * (1 - np.cos(yaw))
    obs[:, 2] = np.angle(np.exp(1j * yaw))
    obs[:, 3], obs[:, 4] = speed, rate
    return obs


def _dataset(obs: np.ndarray, episode: np.ndarray | None = None) -> TransitionDataset:
    n = len(obs) - 1
    command = np.tile([2.0, 0.08], (n, 1))
    episode = np.zeros(n, np.int64) if episode is None else episode
    return TransitionDataset(obs=obs[:-1], command=command, next_obs=obs[1:], dt=0.05, episode=episode)


def test_a_clean_data_set_reports_no_defect():
    report = dataset_quality(_dataset(_circle()))
    assert report.jumps == () and not report.raw and report.rates == () and report.reversing is None
    assert report.speed_scale is not None and report.speed_scale.factor == pytest.approx(1.0, abs=0.01)
    assert [u.match for u in report.units] == ["m/s", "rad/s"]
    assert report.coverage.speed_range == (2.0, 2.0)
    assert report.coverage.curvature_range == pytest.approx((0.25, 0.25))
    assert report.warnings == ()


def test_a_data_set_s_jump_scale_and_unit_are_found_not_removed():
    obs = _circle()
    obs[201:, 0] += 0.8  # the pose jumps between samples 200 and 201
    obs[:, 3] *= 1.1  # the speed reads 10 % high
    obs[:, 4] = np.degrees(obs[:, 4])  # and the yaw rate is in deg/s
    data = _dataset(obs)
    report = dataset_quality(data)
    (jump,) = report.jumps
    assert jump.time_s == pytest.approx(201 * 0.05) and jump.distance_m == pytest.approx(0.8, abs=0.1)
    assert report.jump_transitions == 1 and report.transitions == len(data)
    assert report.speed_scale is not None and report.speed_scale.factor == pytest.approx(1.1, abs=0.01)
    assert report.speed_scale.warning
    rate = {u.signal: u for u in report.units}["yaw_rate"]
    assert rate.suspicious and rate.match == "deg/s"
    assert rate.raw_factor == pytest.approx(180 / math.pi, rel=0.01)
    text = report.to_markdown()
    assert "holding one (kept)" in text and "180/pi" in text
    assert max(len(line) for line in text.splitlines()) <= 100
    record = json.loads(json.dumps(report.to_json()))
    assert record["jumps"][0]["distance_m"] == pytest.approx(jump.distance_m)


def test_windows_never_cross_from_one_episode_to_the_next():
    obs = np.concatenate([_circle(100), _circle(100)])
    obs[101:, :2] += 50.0  # the second episode is far away: a window across would "move" 50 m
    episode = np.r_[np.zeros(100, np.int64), 1 + np.zeros(100, np.int64)]
    rows = np.r_[np.arange(100), np.arange(101, 201)]
    data = TransitionDataset(
        obs=obs[rows], command=np.tile([2.0, 0.0], (200, 1)), next_obs=obs[rows + 1], dt=0.05, episode=episode
    )
    report = dataset_quality(data)
    assert report.speed_scale is not None and 0.99 < report.speed_scale.q25 <= report.speed_scale.q75 < 1.01
    assert [e.transitions for e in report.episodes] == [100, 100] and report.jumps == ()


def test_signal_rates_and_gaps():
    t = np.r_[np.arange(0.0, 5.0, 0.025), np.arange(6.0, 8.0, 0.05)]
    rate = m.signal_rate("pose", "p.csv", t, 0.15)
    assert rate.gaps == (pytest.approx((t[199], 6.0 - t[199])),)
    assert rate.longest_gap_s == pytest.approx(1.025)
    assert rate.median_hz == pytest.approx(40.0) and rate.p5_hz == pytest.approx(20.0)
    assert rate.p95_hz == pytest.approx(40.0) and rate.samples == len(t)


def test_reversing_runs_are_counted_with_their_length():
    t = np.arange(0.0, 10.0, 0.1)
    speed = np.where((t >= 2.0) & (t < 3.0) | (t >= 6.0) & (t < 8.0), -0.5, 1.0)
    reversing = m.reversing(t, speed, excluded=7)
    assert reversing.segments == 2 and reversing.total_s == pytest.approx(3.0)
    assert reversing.longest_s == pytest.approx(2.0) and reversing.slowest_m_s == -0.5
    assert reversing.excluded_samples == 7
    assert m.reversing(t, np.full(t.shape, -0.01), excluded=0).segments == 0  # noise at a standstill


def test_coverage_bins_hold_every_transition():
    speed = np.array([0.1, 0.6, 1.2, 1.3, 3.9])
    rate = np.array([0.0, 0.3, -0.6, 0.6, 40.0])  # the last: 10.3 1/m, counted in the end bin
    cover = m.coverage(speed, rate)
    assert cover.speed.edges == (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0)
    assert cover.speed.counts == (1, 1, 2, 0, 0, 0, 0, 1)
    assert cover.curvature is not None and sum(cover.curvature.counts) == 4
    assert cover.curvature.edges[0] == -3.0 and cover.curvature.counts[-1] == 1
    assert cover.curvature_range == pytest.approx((-0.5, 40.0 / 3.9))
