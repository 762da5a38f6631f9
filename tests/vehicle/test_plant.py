"""Tests of the plant registry and shared plant behaviour."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.track.path import Path
from rkmpc.vehicle.friction import ArcWindowFriction, FrictionChange, FrictionProduct, combine_friction
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.plants.fullsize import FullSizePlant
from rkmpc.vehicle.registry import PLANTS, make_plant


def test_registry_builds_known_plants() -> None:
    assert set(PLANTS) == {"f1tenth", "fullsize"}
    f1 = make_plant("f1tenth")
    assert isinstance(f1, DynamicPlant)
    assert f1.params == f1tenth()
    assert f1.input_delay == 0.0
    with pytest.raises(TypeError):  # settings go to the plant's class, typed, not through the registry
        make_plant("f1tenth", input_delay=0.02)  # type: ignore[call-arg]
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


# --------------------------------------------------------------------------- friction schedules


def _circle_path(radius: float = 5.0) -> Path:
    angles = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    return Path.from_points(np.column_stack([radius * np.cos(angles), radius * np.sin(angles)]))


def test_arc_window_friction_inside_and_outside() -> None:
    path = _circle_path()
    length = path.length
    schedule = ArcWindowFriction(0.6, path, start_s=-0.1 * length, length_s=0.2 * length, max_lateral=1.0)
    assert schedule.start_s == pytest.approx(0.9 * length)
    for fraction, inside in [
        (0.95, True),
        (0.0, True),
        (0.09, True),
        (0.11, False),
        (0.5, False),
        (0.89, False),
    ]:
        for lateral in (-0.9, 0.0, 0.9):
            x, y = path.position(fraction * length) * (1.0 + lateral / 5.0)
            expected = 0.6 if inside else 1.0
            assert schedule(123.0, float(x), float(y)) == expected, (fraction, lateral)
    # Beyond max_lateral from the path (here the circle's centre and far outside) nothing changes.
    assert schedule(0.0, 0.0, 0.0) == 1.0
    assert schedule(0.0, 7.0, 0.0) == 1.0
    assert "factor=0.6" in repr(schedule)


def test_arc_window_friction_validates() -> None:
    path = _circle_path()
    with pytest.raises(ParameterError, match="factor"):
        ArcWindowFriction(0.0, path, 0.0, 1.0, 1.0)
    with pytest.raises(ParameterError, match="length_s"):
        ArcWindowFriction(0.5, path, 0.0, 2.0 * path.length, 1.0)
    with pytest.raises(ParameterError, match="max_lateral"):
        ArcWindowFriction(0.5, path, 0.0, 1.0, math.inf)
    with pytest.raises(ParameterError, match="start_s"):
        ArcWindowFriction(0.5, path, math.nan, 1.0, 1.0)


def test_combine_friction() -> None:
    half = FrictionChange(0.5)
    late = FrictionChange(0.8, start_time=1.0)
    assert combine_friction(None, None) is None
    assert combine_friction(None, half) is half
    both = combine_friction(half, None, late)
    assert isinstance(both, FrictionProduct)
    assert both(0.0, 0.0, 0.0) == 0.5
    assert both(2.0, 0.0, 0.0) == pytest.approx(0.4)
    with pytest.raises(ParameterError):
        FrictionProduct(())


def test_with_mass_scaled_keeps_centre_of_gravity() -> None:
    nominal = f1tenth()
    heavy = nominal.with_mass_scaled(1.3)
    assert heavy.mass == pytest.approx(1.3 * nominal.mass)
    assert heavy.yaw_inertia == pytest.approx(1.3 * nominal.yaw_inertia)
    assert (heavy.lf, heavy.lr, heavy.h_cg) == (nominal.lf, nominal.lr, nominal.h_cg)
    assert replace(heavy, mass=nominal.mass, yaw_inertia=nominal.yaw_inertia) == nominal
    with pytest.raises(ParameterError, match="mass factor"):
        nominal.with_mass_scaled(0.0)
