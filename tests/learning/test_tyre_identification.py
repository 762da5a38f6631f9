"""Tyres from laps: the lateral dynamics predicted, the curves recovered, the nominal kept when unexcited.

The default tier uses one LMPC lap of the built-in track (the dynamic plant, Pacejka tyres); the
slow tier two laps of zoo cars. Tolerances: the curves of a car whose chassis is known within 3 %
over the slip angles the data reach (the fit is exact up to the wheel angle's interpolation within
a period); the gym's linear stiffnesses within 8 % (its bang-bang servo limit-cycles within the
period, so the wheel angle between samples is not their interpolation); without a side-slip
measurement, the ratio of the stiffnesses within 5 % (their scale is only weakly identifiable).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.core.observation import Command
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.tyre_dynamics import Chassis, Runs, predict
from rkmpc.learning.tyre_fit import identify_tyres
from rkmpc.learning.tyre_model import AxleCurve, IdentifiedTyres, nominal_curves
from rkmpc.vehicle.params import PacejkaParams, f1tenth
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.zoo import get_car

T = 0.05


def quiet(data, vehicle, **options) -> IdentifiedTyres:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        return identify_tyres(data, vehicle, **options)


def worst_relative_error(curve: AxleCurve, truth, reach: float) -> float:
    alpha = np.linspace(0.01, reach, 50)
    expected = truth(alpha)
    return float(np.max(np.abs(curve.force_per_load(alpha) - expected) / np.abs(expected)))


def without(data: TransitionDataset, *columns: int) -> TransitionDataset:
    obs, nxt = data.obs.copy(), data.next_obs.copy()
    for c in columns:
        obs[:, c] = nxt[:, c] = np.nan
    return TransitionDataset(obs, data.command, nxt, data.dt, data.episode, data.metadata)


# ---------------------------------------------------------------------------- curves and records


def test_curves_evaluate_validate_and_become_the_tyres_of_a_car():
    linear = AxleCurve.linear(4.0)
    assert linear.stiffness == 4.0 and math.isinf(linear.peak)
    np.testing.assert_allclose(linear.force_per_load(np.array([0.1, -0.2])), [0.4, -0.8])
    pac = AxleCurve.pacejka(5.0, 1.2, 1.5)
    assert pac.stiffness == pytest.approx(9.0) and pac.peak == pytest.approx(1.5, rel=1e-4)
    # The tyre of a car with friction mu gives the same force at mu: the curve holds mu.
    for curve in (linear, pac):
        force = curve.tyre(0.8).build()
        assert force(0.07, 20.0, 0.8) == pytest.approx(20.0 * float(curve.force_per_load(np.array(0.07))))
    front, _ = nominal_curves(replace(f1tenth(), mu=0.7))
    assert front.parameters[2] == pytest.approx(0.7 * 1.8635)
    for bad in (
        {"kind": "cubic", "parameters": (1.0,)},
        {"kind": "linear", "parameters": (1.0, 2.0)},
        {"kind": "linear", "parameters": (-1.0,)},
        {"kind": "pacejka", "parameters": (5.0, 1.0, 9.0, 0.0)},  # D beyond any tyre
        {"kind": "pacejka", "parameters": (5.0, float("nan"), 1.0, 0.0)},
    ):
        with pytest.raises(ParameterError, match="AxleCurve"):
            AxleCurve(**bad)


def _tyres(**changes) -> IdentifiedTyres:
    values = {
        "structure": "linear",
        "front": AxleCurve.linear(4.5),
        "rear": AxleCurve.linear(6.0),
        "status": "identified",
        "status_reason": "test",
        "fitted_on": "slip_angle",
        "wheel": "measured",
        "servo": "identified",
        "n_samples": 500,
        "folds": 5,
        "heldout_score": 0.2,
        "nominal_score": 0.8,
        "slip_reach": (0.1, 0.07),
        "candidates": (("nominal", 0.8), ("linear", 0.2)),
    }
    return IdentifiedTyres(**{**values, **changes})


def test_identified_tyres_validate_and_come_back_from_json():
    from rkmpc.core.jsonutil import to_json_ready

    tyres = _tyres()
    back = IdentifiedTyres.from_json(to_json_ready(tyres))
    assert back.front == tyres.front and back.candidates == tyres.candidates
    assert math.isnan(back.lateral_velocity_rmse)  # None in JSON, NaN again
    assert tyres.error_ratio == pytest.approx(0.25)
    assert tyres.understeer_gradient() == pytest.approx((1 / 4.5 - 1 / 6.0) / 9.81)
    with pytest.raises(ParameterError, match="nominal goes with nominal"):
        _tyres(status="nominal")
    with pytest.raises(ParameterError, match="fitted_on"):
        _tyres(fitted_on="gps")
    with pytest.raises(ParameterError, match="expected the fields"):
        IdentifiedTyres.from_json({"structure": "linear"})


# ---------------------------------------------------------------------------- the dynamics


def test_one_period_predicted_like_the_dynamic_plant():
    """With the wheel and the speed held, the prediction is the plant's chassis, RK4 against RK4."""
    vehicle = f1tenth()
    plant = DynamicPlant(vehicle)
    plant.reset(0.0, 0.0, 0.0, 3.0, 0.12)  # wheel at the command: the servo does not move
    rows = []
    for _ in range(8):  # the transient from the kinematic state of the reset
        before = plant.observe()
        plant.step(Command(3.0, 0.12), T)
        rows.append((before, plant.observe()))
    speed = np.array([[a.speed / math.cos(a.slip_angle), b.speed / math.cos(b.slip_angle)] for a, b in rows])
    runs = Runs(
        speed=speed,
        wheel=np.array([[a.steer_angle, b.steer_angle] for a, b in rows]),
        beta0=np.array([a.slip_angle for a, _ in rows]),
        yaw_rate0=np.array([a.yaw_rate for a, _ in rows]),
        yaw_rate=np.array([[a.yaw_rate, b.yaw_rate] for a, b in rows]),
        lateral=np.full((len(rows), 2), np.nan),
        scored=np.array([[False, True]] * len(rows)),
        dt=T,
    )
    front, rear = nominal_curves(vehicle)
    beta, r = predict(runs, Chassis.of(vehicle), front.force_per_load, rear.force_per_load)
    np.testing.assert_allclose(r[:, 1], [b.yaw_rate for _, b in rows], atol=2e-4)
    np.testing.assert_allclose(beta[:, 1], [b.slip_angle for _, b in rows], atol=2e-5)
    assert np.ptp(r[:, 1]) > 0.1  # from the kinematic yaw rate of the reset to the dynamic one


# ---------------------------------------------------------------------------- identification


def test_wrong_nominal_tyres_are_replaced_by_the_plants_own(builtin_lap):
    truth = f1tenth()
    # The car the controllers are told about has other tyres: stiffer and grippier.
    told = replace(
        truth,
        tyre_front=PacejkaParams(B=8.0, C=0.5, D=2.2, E=0.0),
        tyre_rear=PacejkaParams(B=9.0, C=0.6, D=2.0, E=0.5),
    )
    tyres = quiet(builtin_lap, told)
    assert (tyres.status, tyres.fitted_on, tyres.wheel, tyres.folds) == (
        "identified",
        "slip_angle",
        "measured",
        5,
    )
    assert tyres.structure in ("grip", "pacejka") and tyres.error_ratio < 0.1
    true_front, true_rear = nominal_curves(truth)
    assert worst_relative_error(tyres.front, true_front.force_per_load, tyres.slip_reach[0]) < 0.03
    assert worst_relative_error(tyres.rear, true_rear.force_per_load, tyres.slip_reach[1]) < 0.03
    assert tyres.yaw_rate_rmse < 0.2 * tyres.nominal_yaw_rate_rmse
    assert tyres.slip_reach[0] > 0.05  # the lap loads the tyres


def _straight(speed: float = 2.0, steps: int = 200) -> TransitionDataset:
    plant = DynamicPlant(f1tenth())
    plant.reset(0.0, 0.0, 0.0, speed, 0.0)
    obs, nxt = [], []
    for _ in range(steps):
        obs.append(plant.observe().as_array())
        plant.step(Command(speed, 0.0), T)
        nxt.append(plant.observe().as_array())
    command = np.tile([speed, 0.0], (steps, 1))
    return TransitionDataset(np.array(obs), command, np.array(nxt), T, np.zeros(steps, dtype=int))


def test_a_straight_drive_does_not_excite_the_tyres_nominal_loudly():
    with pytest.warns(IdentificationWarning, match="marked nominal"):
        tyres = identify_tyres(_straight(), f1tenth())
    assert (tyres.status, tyres.structure) == ("nominal", "nominal")
    assert "do not excite the tyres" in tyres.status_reason
    assert (tyres.front, tyres.rear) == nominal_curves(f1tenth())


def test_bad_arguments_are_named():
    with pytest.raises(ParameterError, match="min_speed"):
        identify_tyres(_straight(steps=30), f1tenth(), min_speed=0.0)
    with pytest.raises(ParameterError, match="folds"):
        identify_tyres(_straight(steps=30), f1tenth(), folds=1)


# ---------------------------------------------------------------------------- two laps of zoo cars


@pytest.fixture(scope="module")
def zoo_laps():
    from rkmpc.sim.collect import collect
    from rkmpc.sim.scenario import load_scenario

    out = {}
    for car in ("home", "gym", "low-grip"):
        out[car] = collect(load_scenario("builtin", car=car), controller="lmpc", laps=2, seed=0)
    return out


@pytest.mark.slow
def test_the_home_car_keeps_its_nominal_tyres(zoo_laps):
    tyres = quiet(zoo_laps["home"], f1tenth())
    assert (tyres.status, tyres.folds) == ("nominal", 5)
    assert "no candidate predicts held-out data clearly better" in tyres.status_reason
    # The candidates were fitted and scored: the linear tyres are far worse, the nominal nearly exact.
    scores = dict(tyres.candidates)
    assert scores["linear"] > 100 * scores["nominal"] and scores["nominal"] < 0.01


@pytest.mark.slow
def test_the_gym_cars_linear_tyres_are_recovered(zoo_laps):
    car = get_car("gym")
    tyres = quiet(zoo_laps["gym"], car.params)  # the gym's chassis, known; its tyres not
    assert (tyres.status, tyres.structure) == ("identified", "linear")
    mu = car.params.mu
    assert tyres.front.stiffness == pytest.approx(mu * car.tyre_front.stiffness_per_load, rel=0.08)
    assert tyres.rear.stiffness == pytest.approx(mu * car.tyre_rear.stiffness_per_load, rel=0.08)
    assert tyres.error_ratio < 0.7


@pytest.mark.slow
def test_low_grip_is_found_as_grip(zoo_laps):
    tyres = quiet(zoo_laps["low-grip"], f1tenth())
    assert (tyres.status, tyres.structure) == ("identified", "grip")
    for curve, nominal in zip((tyres.front, tyres.rear), nominal_curves(f1tenth()), strict=True):
        assert curve.parameters[2] / nominal.parameters[2] == pytest.approx(0.7, rel=0.01)


@pytest.mark.slow
def test_without_side_slip_the_ratio_is_identified(zoo_laps):
    car = get_car("gym")
    with pytest.warns(IdentificationWarning, match="side slip is not measured"):
        tyres = identify_tyres(without(zoo_laps["gym"], 5), car.params)
    assert (tyres.status, tyres.fitted_on) == ("identified", "yaw_rate")
    assert tyres.structure in ("ratio", "linear") and math.isnan(tyres.lateral_velocity_rmse)
    truth = car.tyre_front.stiffness_per_load / car.tyre_rear.stiffness_per_load
    assert tyres.front.stiffness / tyres.rear.stiffness == pytest.approx(truth, rel=0.05)


@pytest.mark.slow
def test_without_side_slip_nor_wheel_angle_the_servo_is_chosen_with_the_tyres(zoo_laps):
    from rkmpc.learning.identification import identify

    blind = without(zoo_laps["low-grip"], 5, 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        servo = identify(blind, f1tenth())
    assert servo.fitted_on == "yaw_rate" and servo.servo_delay > 0  # the chassis's yaw lag, as a delay
    with pytest.warns(IdentificationWarning, match="wheel angle is not measured"):
        tyres = identify_tyres(blind, f1tenth(), servo)
    assert any("only their ratio" in w for w in tyres.warnings)  # the scale is the servo's lag's
    names = [name for name, _ in tyres.candidates]
    assert names[:2] == ["nominal", "ratio"] and "nominal, nominal servo" in names
    # Through the identified servo, the chassis's lag counts twice: a servo without the delay wins.
    assert tyres.wheel == "commands" and tyres.servo in ("lag", "nominal")
    assert tyres.heldout_score < 0.5 * tyres.nominal_score
