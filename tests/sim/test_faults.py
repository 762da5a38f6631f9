"""Tests of the named faults and their use in runs."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.core.registry import UnknownNameError
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.faults import (
    DEFAULT_NOISE,
    FAULTS,
    DelayFault,
    Fault,
    FrictionFault,
    HeavyFault,
    NoiseFault,
    apply_fault,
    curviest_window,
    get_fault,
)
from rkmpc.sim.run import RunSpec, build_plant, run_record
from rkmpc.sim.scenario import Scenario, load_scenario
from rkmpc.vehicle.friction import ArcWindowFriction, FrictionChange, FrictionProduct
from rkmpc.vehicle.params import f1tenth, fullsize
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.plants.fullsize import FullSizePlant
from rkmpc.vehicle.sensors import SensedPlant
from rkmpc.vehicle.wrappers import CommandDelay, ObservationNoise


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return load_scenario("builtin")


def drive(
    plant: Plant, commands: list[Command], start: tuple[float, ...] = (0.0, 0.0, 0.0, 2.0, 0.0)
) -> np.ndarray:
    """Reset ``plant`` to ``start``, apply the commands (0.05 s each), return the states after each."""
    plant.reset(*start)
    states = []
    for command in commands:
        plant.step(command, 0.05)
        states.append(plant.state)
    return np.array(states)


# --------------------------------------------------------------------------- registry and validation


def test_registry_holds_the_named_defaults() -> None:
    assert set(FAULTS) == {"noise", "delay", "friction", "heavy"}
    for name, fault in FAULTS.items():
        assert isinstance(fault, Fault)
        assert fault.name == name
        assert get_fault(name) is fault
        record = fault.describe()
        assert record["name"] == name
        assert isinstance(record["parameters"], dict)
    assert FAULTS["noise"] == NoiseFault(DEFAULT_NOISE)
    assert FAULTS["delay"] == DelayFault(0.05)
    assert FAULTS["friction"] == FrictionFault(0.6, 0.2, None)
    assert FAULTS["heavy"] == HeavyFault(1.3, 0.3, True)
    with pytest.raises(dataclasses.FrozenInstanceError):
        FAULTS["delay"].delay = 0.1  # type: ignore[misc]


def test_unknown_fault_lists_known_names(scenario: Scenario) -> None:
    # The registry's message (rkmpc.core.registry): the unknown name, then every known one.
    with pytest.raises(UnknownNameError, match="unknown fault 'ice'; known: noise, delay, friction, heavy"):
        get_fault("ice")
    with pytest.raises(ParameterError, match="unknown fault 'ice'; known: noise, delay, friction, heavy"):
        RunSpec("lmpc", fault="ice")
    with pytest.raises(ParameterError, match="unknown fault 'ice'; known: noise"):
        apply_fault(DynamicPlant(), "ice", scenario, 0)
    with pytest.raises(ParameterError, match="did you mean 'delay'"):
        get_fault("dealy")
    with pytest.raises(ParameterError, match="not a fault"):
        apply_fault(DynamicPlant(), 3, scenario, 0)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="give one of them"):
        RunSpec("lmpc", noise=DEFAULT_NOISE, fault="noise")


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: NoiseFault(std=0.1), "std"),  # type: ignore[arg-type]
        (lambda: DelayFault(0.0), "delay"),
        (lambda: DelayFault(-0.05), "delay"),
        (lambda: DelayFault(math.inf), "delay"),
        (lambda: DelayFault("0.05"), "delay"),  # type: ignore[arg-type]
        (lambda: FrictionFault(factor=0.0), "factor"),
        (lambda: FrictionFault(factor=math.nan), "factor"),
        (lambda: FrictionFault(lap_fraction=0.0), "lap_fraction"),
        (lambda: FrictionFault(lap_fraction=1.5), "lap_fraction"),
        (lambda: FrictionFault(start_fraction=1.0), "start_fraction"),
        (lambda: FrictionFault(start_fraction=-0.1), "start_fraction"),
        (lambda: HeavyFault(mass_factor=0.0), "mass_factor"),
        (lambda: HeavyFault(mass_factor=True), "mass_factor"),  # type: ignore[arg-type]
        (lambda: HeavyFault(tyre_load_sensitivity=1.5), "tyre_load_sensitivity"),
        (lambda: HeavyFault(fixed_drive_force=1), "fixed_drive_force"),  # type: ignore[arg-type]
    ],
)
def test_bad_parameters_rejected(make, field: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError, match=field):
        make()


@pytest.mark.parametrize("name", ["friction", "heavy"])
def test_model_faults_reject_other_plants(name: str, scenario: Scenario) -> None:
    wrapped = ObservationNoise(DynamicPlant(), DEFAULT_NOISE, seed=0)
    with pytest.raises(ParameterError, match=rf"fault '{name}' cannot apply to plant ObservationNoise"):
        apply_fault(wrapped, name, scenario, 0)

    class Subclass(DynamicPlant):
        pass

    with pytest.raises(ParameterError, match=rf"fault '{name}' cannot apply to plant Subclass"):
        apply_fault(Subclass(), name, scenario, 0)


# --------------------------------------------------------------------------- each fault's effect


def test_noise_changes_observations_only_and_is_seeded(scenario: Scenario) -> None:
    commands = [Command(2.0, 0.1)] * 5
    nominal = DynamicPlant()
    noisy = apply_fault(DynamicPlant(), "noise", scenario, seed=4)
    assert isinstance(noisy, ObservationNoise)
    assert noisy.std == DEFAULT_NOISE
    np.testing.assert_array_equal(drive(noisy, commands), drive(nominal, commands))
    assert noisy.observe() != nominal.observe()

    def observations(seed: int) -> list[Observation]:
        plant = apply_fault(DynamicPlant(), "noise", scenario, seed)
        drive(plant, commands)
        return [plant.observe() for _ in range(3)]

    assert observations(4) == observations(4)
    assert observations(4) != observations(5)


def test_delay_shifts_the_response_by_one_period(scenario: Scenario) -> None:
    delayed = apply_fault(DynamicPlant(), "delay", scenario, 0)
    assert isinstance(delayed, CommandDelay)
    assert delayed.steps == 1
    steer_step = [Command(2.0, 0.2)] * 8
    held = [Command(2.0, 0.0)]  # the command the plant was reset to hold
    np.testing.assert_allclose(
        drive(delayed, steer_step), drive(DynamicPlant(), held + steer_step[:-1]), rtol=0.0, atol=1e-12
    )
    assert DelayFault(0.15).steps(0.05) == 3
    with pytest.raises(ParameterError, match="whole number of control periods"):
        apply_fault(DynamicPlant(), DelayFault(0.07), scenario, 0)


def test_friction_window_placement_and_multiplier(scenario: Scenario) -> None:
    fault = FAULTS["friction"]
    assert isinstance(fault, FrictionFault)
    track = scenario.track
    path = track.centerline
    schedule = fault.schedule(track)
    assert schedule.factor == 0.6
    assert schedule.length_s == pytest.approx(0.2 * path.length)
    assert schedule.start_s == curviest_window(path, schedule.length_s)
    assert fault.schedule(track).start_s == schedule.start_s  # deterministic
    assert FrictionFault(start_fraction=0.25).schedule(track).start_s == pytest.approx(0.25 * path.length)
    # Along the centre line and across the track: < 1 inside the window, exactly 1 outside.
    s = np.linspace(0.0, path.length, 400, endpoint=False)
    offset = (s - schedule.start_s) % path.length
    xy = path.position(s)
    normal = np.column_stack([-np.sin(path.heading(s)), np.cos(path.heading(s))])
    for lateral in (-0.7, 0.0, 0.7):
        points = xy + lateral * normal
        factors = np.array([schedule(0.0, float(x), float(y)) for x, y in points])
        inside = (offset > 0.05) & (offset < schedule.length_s - 0.05)
        outside = (offset > schedule.length_s + 0.05) & (offset < path.length - 0.05)
        assert np.all(factors[inside] == 0.6)
        assert np.all(factors[outside] == 1.0)
        assert 0.18 < np.mean(factors < 1.0) < 0.22
    # The window holds the most turning of any stretch of its length.
    turning = np.abs(path.curvature(s))
    inside_turning = turning[offset < schedule.length_s].sum()
    for start in range(0, 400, 20):
        assert inside_turning >= np.roll(turning, -start)[:80].sum() - 1e-9


def test_friction_changes_only_the_friction(scenario: Scenario) -> None:
    plant = DynamicPlant(internal_dt=2e-3, input_delay=0.01)
    faulty = apply_fault(plant, "friction", scenario, 0)
    assert isinstance(faulty, DynamicPlant) and faulty is not plant
    assert faulty.params == plant.params
    assert (faulty.internal_dt, faulty.input_delay) == (2e-3, 0.01)
    assert isinstance(faulty.friction, ArcWindowFriction)
    assert plant.friction is None
    # An existing schedule is kept and multiplied.
    wet = DynamicPlant(friction=FrictionChange(0.9))
    assert isinstance(apply_fault(wet, "friction", scenario, 0).friction, FrictionProduct)  # type: ignore[attr-defined]
    # Outside the window (the start line) the car moves exactly as the nominal one.
    commands = [Command(2.0, 0.0)] * 4
    np.testing.assert_array_equal(
        drive(faulty, commands), drive(DynamicPlant(internal_dt=2e-3, input_delay=0.01), commands)
    )


def _steady_turn(plant: Plant, speed: float = 2.5, steer: float = 0.15) -> tuple[float, float]:
    """Yaw rate (rad/s) and understeer angle ``steer - L r / v`` (rad) after 3 s of a steady turn."""
    states = drive(plant, [Command(speed, steer)] * 60, start=(0.0, 0.0, 0.0, speed, steer))
    yaw_rate = float(states[-1, 5])
    return yaw_rate, steer - f1tenth().wheelbase * yaw_rate / speed


def test_heavy_parameters_and_understeer(scenario: Scenario) -> None:
    fault = FAULTS["heavy"]
    assert isinstance(fault, HeavyFault)
    nominal = f1tenth()
    heavy = fault.vehicle(nominal)
    assert heavy.mass == pytest.approx(1.3 * nominal.mass)
    assert heavy.yaw_inertia == pytest.approx(1.3 * nominal.yaw_inertia)
    assert heavy.mu == pytest.approx(1.3**-0.3)
    assert heavy.drive.time_constant == pytest.approx(1.3 * nominal.drive.time_constant)
    assert heavy.drive.max_accel == pytest.approx(nominal.drive.max_accel / 1.3)
    assert heavy.drive.max_brake == pytest.approx(nominal.drive.max_brake / 1.3)
    same = (heavy.lf, heavy.lr, heavy.h_cg, heavy.steering, heavy.tyre_front, heavy.tyre_rear)
    assert same == (
        nominal.lf,
        nominal.lr,
        nominal.h_cg,
        nominal.steering,
        nominal.tyre_front,
        nominal.tyre_rear,
    )

    plant = apply_fault(DynamicPlant(), fault, scenario, 0)
    assert isinstance(plant, DynamicPlant)
    assert plant.params == heavy
    r_nominal, under_nominal = _steady_turn(DynamicPlant())
    r_heavy, under_heavy = _steady_turn(plant)
    assert r_heavy < r_nominal
    assert under_heavy > under_nominal > 0.0
    # The fixed drive force makes it accelerate later.
    speed_up = [Command(3.0, 0.0)] * 4
    assert drive(plant, speed_up)[-1, 3] < drive(DynamicPlant(), speed_up)[-1, 3] - 0.05


def test_heavy_without_load_sensitivity_or_drive_limit_is_the_same_motion(scenario: Scenario) -> None:
    """Load-proportional tyres: more mass and inertia alone do not change the motion."""
    plant = apply_fault(DynamicPlant(), HeavyFault(1.3, 0.0, False), scenario, 0)
    assert plant.params.mass == pytest.approx(1.3 * f1tenth().mass)
    commands = [Command(2.5 + 0.2 * math.sin(i), 0.2 * math.cos(i)) for i in range(10)]
    np.testing.assert_allclose(drive(plant, commands), drive(DynamicPlant(), commands), rtol=0.0, atol=1e-9)


def test_faults_apply_to_the_fullsize_plant(scenario: Scenario) -> None:
    nominal = FullSizePlant(input_delay=0.02)
    heavy = apply_fault(nominal, "heavy", scenario, 0)
    assert isinstance(heavy, FullSizePlant)
    assert (heavy.mass_scale, heavy.grip_scale) == (1.3, pytest.approx(1.3**-0.3))
    assert heavy.input_delay == 0.02
    assert heavy.params == HeavyFault().vehicle(fullsize())
    twice = apply_fault(heavy, "heavy", scenario, 0)
    assert twice.mass_scale == pytest.approx(1.69)  # type: ignore[attr-defined]
    wet = apply_fault(nominal, "friction", scenario, 0)
    assert isinstance(wet, FullSizePlant) and isinstance(wet.friction, ArcWindowFriction)
    assert (wet.mass_scale, wet.grip_scale) == (1.0, 1.0)
    assert isinstance(apply_fault(nominal, "delay", scenario, 0), CommandDelay)
    assert isinstance(apply_fault(nominal, "noise", scenario, 0), ObservationNoise)


# --------------------------------------------------------------------------- runs


def test_build_plant_and_record(scenario: Scenario) -> None:
    assert isinstance(build_plant(scenario, RunSpec("lmpc")), DynamicPlant)
    plant = build_plant(scenario, RunSpec("lmpc", fault="delay", noise=DEFAULT_NOISE, seed=3))
    assert isinstance(plant, ObservationNoise) and isinstance(plant.plant, CommandDelay)
    assert plant.seed == 3
    runs = run_record(scenario, [RunSpec("lmpc"), RunSpec("pp", fault="friction")])["runs"]
    assert runs[0]["fault"] is None
    assert runs[1]["fault"] == {
        "name": "friction",
        "parameters": {"factor": 0.6, "lap_fraction": 0.2, "start_fraction": None},
    }


@pytest.mark.parametrize("name", ["friction", "heavy"])
def test_a_fault_of_the_car_is_measured_by_the_car_s_sensors(name: str) -> None:
    # Through a real car's sensors the fault changes the car inside them (it failed on the sensed
    # plant before); faults of the signals stay outside them, as with ideal sensors.
    real = Scenario.from_car(load_preset("f1tenth").with_sensors("f1tenth-real"), "builtin")
    plant = build_plant(real, RunSpec("lmpc", fault=name, seed=2))
    assert isinstance(plant, SensedPlant) and isinstance(plant.plant, DynamicPlant)
    faulty = build_plant(load_scenario("builtin"), RunSpec("lmpc", fault=name, seed=2))
    assert type(faulty) is DynamicPlant and plant.plant.params == faulty.params
    inside, nominal = plant.plant, real.make_car_plant(2)
    assert (inside.friction is not None) if name == "friction" else (inside.params != nominal.params)
    delayed = build_plant(real, RunSpec("lmpc", fault="delay", noise=DEFAULT_NOISE))
    assert isinstance(delayed.plant, CommandDelay) and isinstance(delayed.plant.plant, SensedPlant)


@pytest.mark.parametrize("name", ["heavy", "delay"])
def test_runspec_with_fault_drives_lmpc(name: str, scenario: Scenario) -> None:
    nominal, _ = run_controller(scenario, RunSpec("lmpc"))
    result, metrics = run_controller(scenario, RunSpec("lmpc", fault=name))
    assert result.log.metadata["fault"] == name
    assert metrics["progress"] > 0.1
    assert (
        result.log.column("lateral_error")[:50].tolist() != nominal.log.column("lateral_error")[:50].tolist()
    )
