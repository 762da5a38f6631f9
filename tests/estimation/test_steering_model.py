"""The wheel angle from the commands: SteeringModel and its propagators (online and over an array)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator, wheel_angles
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.servo_fit import lag_delay_weights, servo_step
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.registry import make_plant

DT = 0.05


def lag(
    tau: float, delay: float = 0.0, rate: float | None = None, max_angle: float = math.inf
) -> SteeringModel:
    return SteeringModel(time_constant=tau, delay=delay, rate_limit=rate, max_angle=max_angle)


# ---------------------------------------------------------------------------- the model


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("time_constant", 0.0),
        ("time_constant", math.nan),
        ("delay", -0.01),
        ("delay", math.inf),
        ("rate_limit", 0.0),
        ("max_angle", -0.1),
        ("max_angle", math.nan),
    ],
)
def test_a_bad_parameter_is_refused_naming_the_field(field, value):
    kwargs = {"time_constant": 0.1, "max_angle": 0.4, field: value}
    with pytest.raises(ParameterError, match=f"SteeringModel.{field}"):
        SteeringModel(**kwargs)


def test_the_structure_says_which_parts_the_servo_has():
    assert lag(0.1).structure == "lag"
    assert lag(0.1, delay=0.05).structure == "delay-lag"
    assert lag(0.1, rate=3.0).structure == "lag-rate"
    assert lag(0.1, delay=0.05, rate=3.0).structure == "delay-lag-rate"


def test_the_nominal_model_is_the_cars_servo():
    car = f1tenth()
    model = SteeringModel.nominal(car)
    assert (model.time_constant, model.max_angle, model.rate_limit, model.delay) == (
        car.steering.time_constant,
        car.steering.max_angle,
        car.steering.max_rate,
        0.0,
    )
    assert model.describe()["structure"] == "lag-rate"


def test_the_identified_model_gives_its_servo():
    identified = IdentifiedModel(0.08, 0.01, 0.9, 0.5, 400, "delay-lag-rate", 0.12, 2.5)
    model = SteeringModel.from_identified(identified, max_angle=0.4)
    assert (model.time_constant, model.delay, model.rate_limit, model.max_angle) == (0.08, 0.12, 2.5, 0.4)
    assert "delay-lag-rate" in model.source
    plain = SteeringModel.from_identified(IdentifiedModel(0.2, 0.0, math.nan, math.nan, 0, "nominal"))
    assert plain.structure == "lag" and plain.describe()["max_angle_rad"] is None


# ---------------------------------------------------------------------------- the propagator


def test_a_finite_measurement_is_returned_and_the_model_continues_from_it():
    tau = 0.158
    a = math.exp(-DT / tau)
    wheel = WheelAnglePropagator(lag(tau), DT)
    assert wheel.step(0.2) == 0.2  # the first command: the wheel taken as settled there
    assert wheel.step(-0.1, measured=0.05) == 0.05
    assert wheel.step(-0.1) == pytest.approx(a * 0.05 + (1 - a) * -0.1, rel=1e-12)


def test_the_lag_factor_and_weights_are_the_exact_discretisation():
    wheel = WheelAnglePropagator(lag(0.2, delay=0.07), 0.05)
    a, w = lag_delay_weights(0.2, 0.07, 0.05)
    assert wheel.a == a == pytest.approx(math.exp(-0.25))
    assert_array_equal(wheel.weights, w)


def test_without_a_command_the_wheel_is_straight_then_lags_the_first_one():
    wheel = WheelAnglePropagator(lag(0.158), DT)
    assert wheel.step(None) == 0.0
    second = wheel.step(0.3)
    assert 0.0 < second < 0.3  # the servo lags the command
    assert second == pytest.approx((1 - math.exp(-DT / 0.158)) * 0.3)


def test_the_wheel_converges_to_a_held_command_and_reset_forgets():
    wheel = WheelAnglePropagator(lag(0.1), DT)
    wheel.step(0.0)
    values = [wheel.step(0.3) for _ in range(60)]
    assert np.all(np.diff(values) > 0) and values[-1] == pytest.approx(0.3, abs=1e-9)
    wheel.reset()
    assert wheel.step(-0.3) == -0.3
    wheel.reset(initial=0.1)
    assert wheel.step(None) == 0.1


@pytest.mark.parametrize("delay", [0.0, 0.02, 0.05, 0.12])
def test_a_delayed_lag_is_the_recursion_of_lag_delay_weights(delay):
    tau = 0.1
    wheel = WheelAnglePropagator(lag(tau, delay=delay), DT)
    a, w = lag_delay_weights(tau, delay, DT)
    steer = np.random.default_rng(3).uniform(-0.4, 0.4, 40)
    assert wheel.step(steer[0]) == steer[0]
    assert_array_equal(wheel.past_commands, np.full(len(w), steer[0]))
    sent = [steer[0]] * len(w)
    expected = steer[0]
    for u in steer[1:]:
        sent.insert(0, u)  # sent[j] = u_{k-1-j} as of this call
        expected = a * expected + float(np.dot(w, sent[: len(w)]))
        assert wheel.step(u) == pytest.approx(expected, rel=1e-12, abs=1e-15)
        assert_array_equal(wheel.past_commands, sent[: len(w)])


@pytest.mark.parametrize(("delay", "tau", "rate"), [(0.0, 0.1, 1.0), (0.03, 0.05, 2.0), (0.12, 0.2, 0.5)])
def test_a_rate_limited_servo_agrees_with_servo_step(delay, tau, rate):
    """The scalar integration against the identification's own (array) one."""
    wheel = WheelAnglePropagator(lag(tau, delay=delay, rate=rate), DT)
    steer = np.random.default_rng(5).uniform(-0.4, 0.4, 60)
    depth = len(wheel._past)
    history = [steer[0]] * depth
    delta = wheel.step(steer[0])
    for u in steer[1:]:
        history.insert(0, u)
        reference = servo_step(np.array([delta]), np.array([history[:depth]]), DT, delay, tau, rate)[0]
        delta = wheel.step(u)
        assert delta == pytest.approx(reference, abs=1e-12)


def test_commands_are_clipped_to_the_wheels_largest_angle():
    wheel = WheelAnglePropagator(lag(0.05, max_angle=0.3), DT)
    wheel.step(1.0)
    assert wheel.angle == 0.3
    assert max(wheel.step(2.0) for _ in range(20)) == pytest.approx(0.3)
    assert wheel.past_commands[0] == 0.3


def test_a_bad_period_is_refused():
    with pytest.raises(ParameterError, match="dt"):
        WheelAnglePropagator(lag(0.1), 0.0)


@pytest.mark.parametrize(
    "model",
    [lag(0.158), lag(0.1, delay=0.07), lag(0.158, rate=3.2, max_angle=0.42), lag(0.05, delay=0.12, rate=1.5)],
)
def test_the_array_function_is_bit_identical_to_the_propagator(model):
    rng = np.random.default_rng(11)
    steer = rng.uniform(-0.5, 0.5, 200)
    measured = np.where(rng.random(201) < 0.1, rng.uniform(-0.3, 0.3, 201), math.nan)
    offline = wheel_angles(model, DT, steer, initial=0.05, measured=measured)
    wheel = WheelAnglePropagator(model, DT)
    wheel.reset(0.05)
    online = [wheel.step(None, measured[0])] + [
        wheel.step(u, m) for u, m in zip(steer, measured[1:], strict=True)
    ]
    assert_array_equal(offline, online)
    with pytest.raises(ParameterError, match="measured"):
        wheel_angles(model, DT, steer, measured=measured[:-1])


def test_the_nominal_model_follows_the_simulated_cars_wheel():
    """The dynamic plant integrates the same servo (lag and rate limit): the angles agree."""
    car = f1tenth()
    plant = make_plant("f1tenth")
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.0)
    wheel = WheelAnglePropagator(SteeringModel.nominal(car), DT)
    wheel.reset(initial=0.0)
    steer = np.repeat(np.random.default_rng(2).uniform(-0.6, 0.6, 20), 4)  # beyond max_angle too
    angles = [wheel.step(None)]
    truth = [plant.wheel_angle]
    for u in steer:
        plant.step(Command(2.0, float(u)), DT)
        angles.append(wheel.step(float(u)))
        truth.append(plant.wheel_angle)
    # RK4 over the kink where the rate limit starts to act: 2.5e-7 rad.
    assert np.max(np.abs(np.array(angles) - truth)) < 1e-6
    # The rate limit acted: a lag without it would be far off.
    unlimited = wheel_angles(
        lag(car.steering.time_constant, max_angle=car.steering.max_angle), DT, steer, initial=0.0
    )
    assert np.max(np.abs(unlimited - truth)) > 0.005  # 0.008 rad where the limit binds
