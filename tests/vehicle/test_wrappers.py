"""Tests of the plant wrappers."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.wrappers import CommandDelay, NoiseStd, ObservationNoise


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


# --------------------------------------------------------------------------- CommandDelay


def _steer_step_response(plant: Plant, n: int = 12) -> np.ndarray:
    """Wheel angles after each of ``n`` steps of a steering step from 0 to 0.2 rad at 2 m/s."""
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.0)
    angles = []
    for _ in range(n):
        plant.step(Command(2.0, 0.2), 0.05)
        angles.append(plant.wheel_angle)
    return np.array(angles)


@pytest.mark.parametrize("steps", [1, 3])
def test_command_delay_shifts_step_response_by_exactly_k_steps(steps: int) -> None:
    nominal = _steer_step_response(DynamicPlant())
    delayed = _steer_step_response(CommandDelay(DynamicPlant(), steps))
    # The initial command (straight wheels) is held for k steps, then the response repeats.
    np.testing.assert_array_equal(delayed[:steps], 0.0)
    np.testing.assert_allclose(delayed[steps:], nominal[:-steps], rtol=0.0, atol=1e-12)
    assert nominal[0] > 0.0


def test_command_delay_holds_the_reset_command_and_equals_an_input_delay() -> None:
    rng = np.random.default_rng(3)
    commands = [Command(2.0 + 0.3 * rng.standard_normal(), 0.2 * rng.standard_normal()) for _ in range(15)]
    wrapped = CommandDelay(DynamicPlant(), 2)
    inner_delay = DynamicPlant(input_delay=0.1)
    for plant in (wrapped, inner_delay):
        plant.reset(1.0, -1.0, 0.3, 2.5, 0.1)
    for command in commands:
        wrapped.step(command, 0.05)
        inner_delay.step(command, 0.05)
        np.testing.assert_allclose(wrapped.state, inner_delay.state, rtol=0.0, atol=1e-12)
    # Reset refills the queue with the new reset command.
    wrapped.reset(0.0, 0.0, 0.0, 1.0, 0.0)
    wrapped.step(Command(3.0, 0.3), 0.05)
    wrapped.step(Command(3.0, 0.3), 0.05)
    assert wrapped.wheel_angle == 0.0
    assert wrapped.time == pytest.approx(0.1)


def test_command_delay_zero_is_identity_and_validates() -> None:
    nominal = _steer_step_response(DynamicPlant(), n=4)
    np.testing.assert_array_equal(_steer_step_response(CommandDelay(DynamicPlant(), 0), n=4), nominal)
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(ParameterError, match="steps"):
            CommandDelay(DynamicPlant(), bad)  # type: ignore[arg-type]
    plant = CommandDelay(DynamicPlant(), 2)
    with pytest.raises(ValueError, match="finite"):
        plant.step(Command(float("nan"), 0.0), 0.05)
    with pytest.raises(ValueError, match="dt"):
        plant.step(Command(1.0, 0.0), 0.0)
