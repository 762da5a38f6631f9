"""Tests of the full-size (BMW 320i, CommonRoad drift model) plant."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.vehicle.friction import FrictionChange
from rkmpc.vehicle.params import fullsize
from rkmpc.vehicle.plants.fullsize import FullSizePlant
from rkmpc.vehicle.tyres import pacejka_lateral_force


def test_preset_matches_package() -> None:
    p = fullsize()
    package = parameters_vehicle2()
    assert p.name == "fullsize"
    assert p.mass == package.m
    assert p.yaw_inertia == package.I_z
    assert (p.lf, p.lr) == (package.a, package.b)
    assert p.h_cg == package.h_s
    assert p.steering.max_angle == package.steering.max
    assert p.steering.max_rate == package.steering.v_max
    assert p.drive.max_accel <= package.longitudinal.a_max
    assert p.drive.max_brake <= package.longitudinal.a_max


def test_preset_tyre_is_package_pure_lateral_force() -> None:
    from vehiclemodels.utils.tire_model import formula_lateral

    p = fullsize()
    tire = parameters_vehicle2().tire
    for alpha in (-0.3, -0.05, 0.01, 0.1, 0.4):
        # The package's slip angle has the opposite sign convention.
        package_force = formula_lateral(-alpha, 0.0, 4000.0, tire)[0]
        ours = pacejka_lateral_force(alpha, 4000.0, p.tyre_front, 1.0)
        assert ours == pytest.approx(package_force, rel=1e-12)


def test_straight_at_constant_speed() -> None:
    plant = FullSizePlant()
    assert len(plant.state) == len(plant.STATE_NAMES) == 9
    plant.reset(0.0, 0.0, 0.0, 15.0)
    for _ in range(60):
        plant.step(Command(15.0, 0.0), 0.05)
    obs = plant.observe()
    assert obs.time == pytest.approx(3.0)
    assert obs.x == pytest.approx(45.0, rel=1e-3)
    # The package's tyre has small offsets (p_hx1, r_vy*) that pull the car slightly sideways.
    assert abs(obs.y) < 0.02
    assert abs(obs.yaw) < 1e-3
    assert obs.speed == pytest.approx(15.0, abs=1e-3)


def test_low_speed_cornering_matches_kinematic_radius() -> None:
    plant = FullSizePlant()
    speed, steer = 3.0, 0.1
    plant.reset(0.0, 0.0, 0.0, speed, 0.0)
    for _ in range(200):
        plant.step(Command(speed, steer), 0.05)
    p = plant.params
    radius = plant.state[3] / plant.state[5]
    kinematic = math.hypot(p.lr, p.wheelbase / math.tan(steer))
    assert plant.wheel_angle == pytest.approx(steer, abs=1e-6)
    assert radius == pytest.approx(kinematic, rel=0.02)


def test_sinusoidal_steering_stays_finite_and_respects_servo() -> None:
    plant = FullSizePlant(friction=FrictionChange(0.7, start_time=10.0))
    plant.reset(0.0, 0.0, 0.0, 20.0)
    angles = []
    for k in range(400):
        plant.step(Command(20.0, 0.05 * math.sin(0.1 * k)), 0.05)
        angles.append(plant.wheel_angle)
    assert np.all(np.isfinite(plant.state))
    assert plant.time == pytest.approx(20.0)
    assert np.max(np.abs(np.diff(angles))) <= plant.params.steering.max_rate * 0.05 + 1e-6
    assert plant.state[3] == pytest.approx(20.0, rel=0.02)


def test_input_delay() -> None:
    immediate = FullSizePlant()
    delayed = FullSizePlant(input_delay=0.1)
    for plant in (immediate, delayed):
        plant.reset(0.0, 0.0, 0.0, 5.0)
    angles_now, angles_late = [], []
    for _ in range(10):
        immediate.step(Command(5.0, 0.05), 0.05)
        delayed.step(Command(5.0, 0.05), 0.05)
        angles_now.append(immediate.wheel_angle)
        angles_late.append(delayed.wheel_angle)
    assert angles_late[:2] == [0.0, 0.0]
    np.testing.assert_allclose(angles_late[2:], angles_now[:-2], atol=1e-6)


def test_mass_and_grip_scale() -> None:
    nominal = FullSizePlant()
    scaled = FullSizePlant(mass_scale=1.3, grip_scale=0.9)
    package = parameters_vehicle2()
    assert scaled._model.m == pytest.approx(1.3 * package.m)
    assert scaled._model.I_z == pytest.approx(1.3 * package.I_z)
    for key in ("p_dx1", "p_dy1", "p_kx1", "p_ky1"):
        assert getattr(scaled._model.tire, key) == pytest.approx(0.9 * getattr(package.tire, key))
    assert nominal._model.m == package.m
    # Friction acts on top of the scaled grip, and a reset restores it.
    wet = FullSizePlant(grip_scale=0.9, friction=FrictionChange(0.5))
    wet.reset(0.0, 0.0, 0.0, 10.0)
    wet.step(Command(10.0, 0.0), 0.01)
    assert wet._model.tire.p_dy1 == pytest.approx(0.45 * package.tire.p_dy1)
    wet.reset(0.0, 0.0, 0.0, 10.0)
    assert wet._model.tire.p_dy1 == pytest.approx(0.9 * package.tire.p_dy1)
    for bad in ({"mass_scale": 0.0}, {"grip_scale": math.nan}):
        with pytest.raises(ParameterError):
            FullSizePlant(**bad)
