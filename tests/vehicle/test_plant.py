"""Tests of the plant registry and shared plant behaviour."""

from __future__ import annotations

import pytest

from rkmpc.control.base import Command
from rkmpc.vehicle.dynamic import DynamicPlant
from rkmpc.vehicle.fullsize import FullSizePlant
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.plant import PLANTS, Plant, make_plant


def test_registry_builds_known_plants() -> None:
    assert set(PLANTS) == {"f1tenth", "fullsize"}
    f1 = make_plant("f1tenth", input_delay=0.02)
    assert isinstance(f1, DynamicPlant)
    assert f1.params == f1tenth()
    assert f1.input_delay == 0.02
    full = make_plant("fullsize")
    assert isinstance(full, FullSizePlant)
    assert full.params.name == "fullsize"


def test_unknown_plant_lists_known_names() -> None:
    with pytest.raises(ValueError, match="f1tenth, fullsize"):
        make_plant("carsim")


@pytest.mark.parametrize("name", sorted(PLANTS))
def test_time_and_reset(name: str) -> None:
    plant: Plant = make_plant(name)
    plant.reset(1.0, 2.0, 0.5, 3.0, 0.05)
    assert plant.time == 0.0
    assert plant.wheel_angle == pytest.approx(0.05)
    for _ in range(3):
        plant.step(Command(3.0, 0.05), 0.05)
    assert plant.time == pytest.approx(0.15)
    # An irregular period is fine.
    plant.step(Command(3.0, 0.05), 0.0123)
    assert plant.time == pytest.approx(0.1623)
    plant.reset(0.0, 0.0, 0.0, 0.0)
    assert plant.time == 0.0
    assert plant.observe().speed == 0.0
