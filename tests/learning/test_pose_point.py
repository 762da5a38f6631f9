"""The pose point of a data set (:mod:`rkmpc.learning.data.quality.pose_point`) on made-up driving."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.quality.pose_point import pose_point

DT = 0.05


def _drive(offset: float, curvature: np.ndarray, noise: float = 0.0, seed: int = 0) -> TransitionDataset:
    """A rear axle that does not slide, on ``curvature`` (1/m) at 1-3 m/s; the pose ``offset`` m ahead."""
    rng = np.random.default_rng(seed)
    n = curvature.size
    x = y = yaw = 0.0
    axle = np.zeros((n + 1, 3))
    speed = 2.0 + np.sin(np.arange(n + 1) * DT * 2 * np.pi / 17.0)
    for k in range(n):
        axle[k] = (x, y, yaw)
        d = speed[k] * DT
        x += d * np.cos(yaw + 0.5 * d * curvature[k])
        y += d * np.sin(yaw + 0.5 * d * curvature[k])
        yaw += d * curvature[k]
    axle[n] = (x, y, yaw)
    pose = axle.copy()
    pose[:, 0] += offset * np.cos(axle[:, 2]) + noise * rng.standard_normal(n + 1)
    pose[:, 1] += offset * np.sin(axle[:, 2]) + noise * rng.standard_normal(n + 1)
    obs = np.zeros((n + 1, 7))
    obs[:, :3] = pose
    obs[:, 3] = speed
    obs[:, 4] = speed * np.append(curvature, curvature[-1])
    obs[:, 5:] = np.nan
    command = np.column_stack([speed[:-1], np.arctan(0.3 * curvature)])
    return TransitionDataset(obs[:-1], command, obs[1:], DT, np.zeros(n, dtype=int))


SLALOM = 1.2 * np.sin(np.arange(2000) * DT * 2 * np.pi / 6.0)


@pytest.mark.parametrize("offset", [0.0, 0.15, 0.4])
def test_the_point_is_found_where_it_is(offset):
    point = pose_point(_drive(offset, SLALOM, noise=0.003), expected=0.15)
    assert point is not None and point.offset_m == pytest.approx(offset, abs=max(4 * point.std_error_m, 0.01))
    assert point.consistent is (offset == 0.15)
    assert 0 < point.std_error_m < 0.02 and point.samples > 1800


def test_no_verdict_without_an_expected_point_and_no_fit_without_turning():
    point = pose_point(_drive(0.15, SLALOM))
    assert point is not None and point.expected_m is None and point.consistent is None
    assert pose_point(_drive(0.15, np.zeros(2000)), expected=0.15) is None  # a straight tells nothing
    assert pose_point(_drive(0.15, SLALOM[:30]), expected=0.15) is None  # too few steps
