"""Tests of the plant wrappers."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control.base import Command
from rkmpc.errors import ParameterError
from rkmpc.vehicle.dynamic import DynamicPlant
from rkmpc.vehicle.wrappers import NoiseStd, ObservationNoise


def noisy(std: NoiseStd, seed: int = 7) -> ObservationNoise:
    plant = ObservationNoise(DynamicPlant(), std, seed=seed)
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.1)
    return plant


def test_zero_noise_is_identity_and_forwards() -> None:
    plant = noisy(NoiseStd())
    plant.step(Command(2.0, 0.1), 0.05)
    assert plant.observe() == plant.plant.observe()
    assert plant.STATE_NAMES == plant.unwrapped.STATE_NAMES
    np.testing.assert_array_equal(plant.state, plant.unwrapped.state)
    assert plant.time == plant.unwrapped.time
    assert plant.wheel_angle == plant.unwrapped.wheel_angle
    assert plant.params is plant.unwrapped.params


def test_seeded_noise_is_reproducible_and_reset_reseeds() -> None:
    std = NoiseStd(position=0.1, yaw=0.01, speed=0.05, yaw_rate=0.02)
    first = [noisy(std).observe() for _ in range(1)] + []
    a, b = noisy(std), noisy(std)
    seq_a = [a.observe() for _ in range(5)]
    seq_b = [b.observe() for _ in range(5)]
    assert seq_a == seq_b
    assert seq_a[0] == first[0]
    assert seq_a[0] != seq_a[1]
    a.reset(0.0, 0.0, 0.0, 2.0, 0.1)
    assert a.observe() == seq_a[0]
    assert noisy(std, seed=8).observe() != seq_a[0]


def test_noise_standard_deviations() -> None:
    std = NoiseStd(position=0.2, yaw=0.01, speed=0.05, yaw_rate=0.0)
    plant = noisy(std)
    true = plant.plant.observe()
    samples = np.array([plant.observe().as_array() for _ in range(4000)]) - true.as_array()
    measured = samples[:, :5].std(axis=0)
    np.testing.assert_allclose(measured[:4], [0.2, 0.2, 0.01, 0.05], rtol=0.05)
    assert measured[4] == 0.0
    np.testing.assert_allclose(samples[:, :4].mean(axis=0), 0.0, atol=0.02)


def test_negative_std_rejected() -> None:
    with pytest.raises(ParameterError):
        NoiseStd(position=-0.1)
