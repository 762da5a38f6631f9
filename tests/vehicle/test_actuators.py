"""Steering actuators, speed loops and tyre models against hand-computed responses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.actuators import (
    AsymmetricSpeedLoop,
    DelayedRateServo,
    FirstOrderServo,
    LagSpeedLoop,
    QuantisedServo,
    SecondOrderServo,
)
from rkmpc.vehicle.params import PacejkaParams
from rkmpc.vehicle.tyres import LinearTyre, PacejkaTyre, pacejka_lateral_force

H = 1e-3


def _response(spec, command: float, seconds: float, h: float = H) -> np.ndarray:
    actuator = spec.build()
    actuator.reset(0.0)
    return np.array([actuator.advance(command, h) for _ in range(round(seconds / h))])


def test_first_order_servo_follows_the_exponential() -> None:
    angle = _response(FirstOrderServo(time_constant=0.1, max_rate=100.0), 0.2, 0.5)
    t = H * np.arange(1, angle.size + 1)
    np.testing.assert_allclose(angle, 0.2 * (1.0 - np.exp(-t / 0.1)), rtol=1e-12, atol=1e-15)


def test_first_order_servo_is_rate_limited() -> None:
    angle = _response(FirstOrderServo(time_constant=0.01, max_rate=2.0), 0.2, 0.05)
    # 2 rad/s for 50 ms: 0.1 rad, a straight line, far from the 0.2 the lag alone would reach.
    np.testing.assert_allclose(angle, 2.0 * H * np.arange(1, 51), rtol=1e-12)


def test_delayed_rate_servo_waits_then_moves_at_its_rate_and_limit_cycles() -> None:
    spec = DelayedRateServo(delay=0.02, max_rate=3.2, update_period=0.01)
    angle = _response(spec, 0.1, 0.2)
    # Nothing for the 20 ms delay, then 3.2 rad/s until the 50 ms decision.
    assert np.all(angle[:20] == 0.0)
    assert angle[29] == pytest.approx(3.2 * 0.010, abs=1e-12)  # t = 30 ms
    assert angle[49] == pytest.approx(3.2 * 0.030, abs=1e-12)  # t = 50 ms: 0.096 < 0.1, keeps going
    assert angle[59] == pytest.approx(3.2 * 0.040, abs=1e-12)  # t = 60 ms: 0.128, turns back
    # Then it never settles: it swings about the command by up to rate * period.
    tail = angle[100:]
    assert tail.max() - tail.min() == pytest.approx(3.2 * 0.01, abs=1e-9)
    assert np.all(np.abs(tail - 0.1) <= 3.2 * 0.01 + 1e-9)


def test_second_order_servo_overshoot_and_peak_time() -> None:
    wn, zeta = 25.0, 0.45
    angle = _response(SecondOrderServo(natural_frequency=wn, damping=zeta, max_rate=100.0), 0.1, 0.6)
    overshoot = angle.max() / 0.1 - 1.0
    assert overshoot == pytest.approx(math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2)), rel=1e-3)
    peak_time = H * (int(np.argmax(angle)) + 1)
    assert peak_time == pytest.approx(math.pi / (wn * math.sqrt(1 - zeta**2)), abs=H)
    # The whole step response, exactly: 1 - exp(-zeta wn t) (cos wd t + zeta / sqrt(1 - zeta^2) sin wd t).
    t = H * np.arange(1, angle.size + 1)
    wd = wn * math.sqrt(1 - zeta**2)
    exact = 0.1 * (
        1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))
    )
    np.testing.assert_allclose(angle, exact, atol=1e-12)


def test_second_order_servo_is_rate_limited() -> None:
    angle = _response(SecondOrderServo(natural_frequency=60.0, damping=0.7, max_rate=1.0), 0.3, 0.1)
    assert np.max(np.abs(np.diff(angle))) <= 1.0 * H + 1e-12


def test_quantised_servo_sits_on_multiples_of_its_step() -> None:
    inner = FirstOrderServo(time_constant=0.1, max_rate=100.0)
    angle = _response(QuantisedServo(inner, step=0.01), 0.123, 1.0)
    np.testing.assert_allclose(angle / 0.01, np.round(angle / 0.01), atol=1e-9)
    assert angle[-1] == pytest.approx(0.12)
    continuous = _response(inner, 0.123, 1.0)
    assert np.max(np.abs(angle - continuous)) <= 0.005 + 1e-12


def test_quantising_twice_is_refused() -> None:
    with pytest.raises(ParameterError, match="already quantised"):
        QuantisedServo(QuantisedServo(FirstOrderServo(0.1, 1.0), 0.01), 0.01)


def test_bad_settings_name_the_field() -> None:
    with pytest.raises(ParameterError, match=r"FirstOrderServo.time_constant"):
        FirstOrderServo(0.0, 1.0)
    with pytest.raises(ParameterError, match=r"DelayedRateServo.delay"):
        DelayedRateServo(-0.01, 1.0)
    with pytest.raises(ParameterError, match=r"SecondOrderServo.damping"):
        SecondOrderServo(10.0, 0.0, 1.0)
    with pytest.raises(ParameterError, match=r"AsymmetricSpeedLoop.brake_gain"):
        AsymmetricSpeedLoop(1.0, math.nan, 1.0, 1.0)


def test_lag_speed_loop() -> None:
    accel = LagSpeedLoop(time_constant=0.5, max_accel=3.0, max_brake=6.0).build()
    assert accel(3.0, 2.0) == pytest.approx(2.0)
    assert accel(10.0, 2.0) == 3.0
    assert accel(0.0, 5.0) == -6.0
    assert accel(0.0, 0.0) == 0.0


def test_asymmetric_speed_loop_uses_its_own_gain_each_way() -> None:
    accel = AsymmetricSpeedLoop(accel_gain=2.0, brake_gain=5.0, max_accel=4.0, max_brake=3.0).build()
    assert accel(3.0, 2.0) == pytest.approx(2.0)  # 2/s x 1 m/s
    assert accel(2.0, 2.5) == pytest.approx(-2.5)  # 5/s x -0.5 m/s
    assert accel(10.0, 2.0) == 4.0
    assert accel(0.0, 2.0) == -3.0
    assert accel(-1.0, 0.0) == 0.0  # never pushes a car at rest backwards


def test_linear_tyre_has_no_saturation() -> None:
    force = LinearTyre(stiffness_per_load=4.718).build()
    assert force(0.05, 20.0, 1.0) == pytest.approx(4.718 * 20.0 * 0.05)
    assert force(0.5, 20.0, 1.0) == pytest.approx(10.0 * force(0.05, 20.0, 1.0))
    assert force(0.05, 20.0, 0.5) == pytest.approx(0.5 * force(0.05, 20.0, 1.0))


def test_pacejka_tyre_matches_the_magic_formula_and_saturates() -> None:
    params = PacejkaParams(B=5.5405, C=0.4182, D=1.8635, E=0.3722)
    force = PacejkaTyre(params).build()
    for alpha in (-0.3, 0.01, 0.1, 0.4):
        assert force(alpha, 17.0, 0.8) == pacejka_lateral_force(alpha, 17.0, params, 0.8)
    b, c, d, e = 5.5405, 0.4182, 1.8635, 0.3722
    ba = b * 0.1
    assert force(0.1, 10.0, 1.0) == pytest.approx(
        10.0 * d * math.sin(c * math.atan(ba - e * (ba - math.atan(ba))))
    )
    assert abs(force(1.5, 10.0, 1.0)) <= 10.0 * d
