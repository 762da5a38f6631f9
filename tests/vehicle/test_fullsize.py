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


#: The state at which LSODA gave up under the LMPC on Catalunya (t = 95.35 s): the car has spun
#: (side slip -2.3 rad, sliding backwards along its heading), front wheel locked at the model's
#: clamp omega >= 0, rear wheel nearly so.
_SPUN_STATE = [
    -669.5077641206426,
    -589.8521595334522,
    -0.6829065469085316,
    14.950332261535598,
    -5.3095074669321,
    1.9436405314261367,
    -2.3159149212855437,
    0.0,
    0.029131979061440754,
]
_SPUN_COMMAND = Command(speed=11.975426594736195, steer=-0.7409786875319553)


def _spun_plant() -> FullSizePlant:
    plant = FullSizePlant()
    plant.reset(_SPUN_STATE[0], _SPUN_STATE[1], _SPUN_STATE[4], 12.462416916427397, -0.7209786875319553)
    plant._s = np.array(_SPUN_STATE)
    return plant


def test_lsoda_alone_fails_on_the_spun_car() -> None:
    """The condition of the Catalunya failure: LSODA alone cannot integrate one period from it."""
    import warnings

    from scipy.integrate import solve_ivp

    plant = _spun_plant()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        solution = solve_ivp(
            plant._rhs,
            (0.0, 0.05),
            np.array(_SPUN_STATE),
            method="LSODA",
            args=(_SPUN_COMMAND.speed, _SPUN_COMMAND.steer),
            rtol=1e-6,
            atol=1e-6,
            max_step=1e-3,
            first_step=1e-3,
        )
    assert not solution.success


def test_spun_car_steps_on_with_a_fallback_integrator() -> None:
    plant = _spun_plant()
    for _ in range(6):
        plant.step(_SPUN_COMMAND, 0.05)
    assert plant.time == pytest.approx(0.3)
    assert plant.fallback_steps >= 1
    state = plant.state
    assert np.isfinite(state).all()
    # Still sliding, wheel speeds inside the model's range.
    assert abs(state[6]) > math.pi / 2
    assert state[7] >= 0.0 and state[8] >= 0.0
    # The car kept moving from where it was (no jump).
    assert 1.0 < math.hypot(state[0] - _SPUN_STATE[0], state[1] - _SPUN_STATE[1]) < 10.0
    plant.reset(0.0, 0.0, 0.0, 10.0)
    assert plant.fallback_steps == 0


def test_integration_failure_raises_plant_integration_error(monkeypatch) -> None:
    from rkmpc.core.errors import PlantIntegrationError

    plant = FullSizePlant()
    plant.reset(0.0, 0.0, 0.0, 10.0)
    monkeypatch.setattr(plant, "_rhs", lambda t, s, v, d: [math.nan] * len(s))
    before = plant.state
    with pytest.raises(PlantIntegrationError, match=r"LSODA.*BDF.*Radau") as info:
        plant.step(Command(10.0, 0.0), 0.05)
    assert info.value.time == 0.0
    # Nothing was advanced.
    assert plant.time == 0.0
    np.testing.assert_array_equal(plant.state, before)
