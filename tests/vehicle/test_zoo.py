"""The car zoo: composed plants, named variants, random draws and delayed odometry."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.wrappers import ObservationDelay
from rkmpc.vehicle.zoo import ZOO, get_car, random_car, zoo_names


def _drive(plant, steps: int = 200) -> np.ndarray:
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.0)
    for k in range(steps):
        plant.step(Command(2.0 + 1.5 * np.sin(k / 30), 0.3 * np.sin(k / 17)), 0.05)
    return plant.state


def test_home_variant_moves_like_the_project_car() -> None:
    composed = _drive(get_car("home").make_plant())
    reference = _drive(DynamicPlant())
    # Same chassis and parts; only the servo's integration differs (exact lag step vs RK4).
    np.testing.assert_allclose(composed, reference, atol=2e-3)


@pytest.mark.parametrize("name", zoo_names())
def test_every_variant_drives_and_differs_only_where_documented(name: str) -> None:
    car = get_car(name)
    assert car.name == name
    state = _drive(car.make_plant(), steps=60)
    assert np.all(np.isfinite(state))
    json.dumps(car.describe())


def test_variants_change_what_they_say() -> None:
    nominal = f1tenth()
    gym = get_car("gym").params
    assert gym.wheelbase == pytest.approx(0.3302)
    assert gym.mass == 3.74
    heavy = get_car("heavy-long").params
    assert heavy.mass == pytest.approx(1.3 * nominal.mass)
    assert heavy.wheelbase == pytest.approx(1.1 * nominal.wheelbase)
    assert heavy.lf / heavy.wheelbase == pytest.approx(nominal.lf / nominal.wheelbase + 0.1)
    light = get_car("light-short").params
    assert light.wheelbase == pytest.approx(0.9 * nominal.wheelbase)
    assert light.lf / light.wheelbase == pytest.approx(nominal.lf / nominal.wheelbase - 0.1)
    assert get_car("low-grip").params.mu == 0.7
    assert get_car("laggy-odom").odometry_latency == 0.04


def test_random_cars_are_reproducible_and_vary() -> None:
    assert random_car(3) == random_car(3)
    assert get_car("random-3") == random_car(3)
    cars = [random_car(seed) for seed in range(8)]
    assert len({c.params.mass for c in cars}) == 8
    assert len({type(c.steering).__name__ for c in cars}) >= 2
    for car in cars:
        assert 0.7 * f1tenth().mass <= car.params.mass <= 1.3 * f1tenth().mass
        assert np.all(np.isfinite(_drive(car.make_plant(seed=1), steps=20)))


def test_unknown_car_lists_the_known_ones() -> None:
    with pytest.raises(ParameterError, match=r"unknown zoo car 'nope'.*gym.*random-<seed>"):
        get_car("nope")
    with pytest.raises(ParameterError):
        get_car("random-x")
    assert set(ZOO) == set(zoo_names())


def test_delayed_odometry_returns_what_was_true_latency_ago() -> None:
    plain = DynamicPlant()
    delayed = ObservationDelay(DynamicPlant(), latency=0.04)
    truth = {}
    plain.reset(0.0, 0.0, 0.0, 2.0, 0.0)
    delayed.reset(0.0, 0.0, 0.0, 2.0, 0.0)
    for k in range(40):
        command = Command(2.5, 0.2 * np.sin(k / 5))
        for _ in range(10):  # the plain plant in the delayed one's 5 ms pieces
            plain.step(command, 0.005)
            truth[round(plain.time, 6)] = plain.observe()
        delayed.step(command, 0.05)
        seen = delayed.observe()
        assert seen.time == pytest.approx(delayed.time - 0.04)
        expected = truth[round(seen.time, 6)]
        assert seen.x == pytest.approx(expected.x, abs=1e-12)
        assert seen.yaw == pytest.approx(expected.yaw, abs=1e-12)


def test_delayed_odometry_refuses_bad_settings() -> None:
    with pytest.raises(ParameterError, match="latency"):
        ObservationDelay(DynamicPlant(), latency=-0.01)
