"""identify() on simulated steering actuators: structure by fit, bounds, nominal fall-backs, warnings.

Each actuator runs at a 1 ms step behind a pure delay, driven by seeded random steps and
ramps; the wheel angle is sampled every control period T = 0.05 s, and speed and yaw rate
follow a kinematic car with understeer gradient 0.01 s^2/m.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np
import pytest

from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import (
    TIME_CONSTANT_RANGE,
    UNDERSTEER_RANGE,
    command_history,
    identify,
)
from rkmpc.learning.servo_fit import SERVO_MIN_R2
from rkmpc.vehicle.params import f1tenth

T = 0.05
STEP = 0.001
WHEELBASE = 0.307
GRADIENT = 0.01
N = 1200
VEHICLE = f1tenth()  # nominal servo lag 0.158 s, wheelbase 0.307 m

#: One actuator step: (wheel angle, wheel rate, delayed command, step index) -> (angle, rate).
Actuator = Callable[[float, float, float, int], tuple[float, float]]


def commands(n: int, seed: int) -> np.ndarray:
    """Steering commands (rad): random steps and ramps held 1 to 8 periods, within +-0.35 rad."""
    rng = np.random.default_rng(seed)
    out = np.empty(n)
    k, last = 0, 0.0
    while k < n:
        hold = int(rng.integers(1, 9))
        target = float(rng.uniform(-0.35, 0.35))
        stretch = np.full(hold, target) if rng.random() < 0.5 else np.linspace(last, target, hold + 1)[1:]
        out[k : k + hold] = stretch[: n - k]
        k += hold
        last = target
    return out


def lag(tau: float) -> Actuator:
    keep = math.exp(-STEP / tau)
    return lambda d, r, u, i: (u + (d - u) * keep, 0.0)


def bang_bang(rate: float, every: int) -> Actuator:
    """Moves ``rate * every`` ms towards the command every ``every`` steps: it never settles."""
    jump = rate * every * STEP
    return lambda d, r, u, i: (d + math.copysign(jump, u - d), 0.0) if i % every == 0 else (d, 0.0)


def second_order(wn: float, zeta: float) -> Actuator:
    def step(d: float, r: float, u: float, i: int) -> tuple[float, float]:
        r += STEP * (wn * wn * (u - d) - 2.0 * zeta * wn * r)
        return d + STEP * r, r

    return step


def wheel_angles(cmd: np.ndarray, actuator: Actuator, delay: float = 0.0) -> np.ndarray:
    """The wheel angle at the start of each period and after the last, shape (n + 1,)."""
    sub = round(T / STEP)
    held = np.repeat(cmd, sub)
    lag_steps = round(delay / STEP)
    delayed = np.concatenate([np.full(lag_steps, cmd[0]), held[: len(held) - lag_steps]])
    d, r = float(cmd[0]), 0.0
    out = np.empty(len(cmd) + 1)
    out[0] = d
    for i, u in enumerate(delayed.tolist()):
        d, r = actuator(d, r, u, i)
        if (i + 1) % sub == 0:
            out[(i + 1) // sub] = d
    return out


def dataset(
    cmd: np.ndarray,
    wheel: np.ndarray,
    *,
    measured: np.ndarray | None = None,
    gradient: float = GRADIENT,
    yaw_rate_noise: float = 0.0,
    speed_scale: float = 1.0,
) -> TransitionDataset:
    """Transitions of a car whose wheel angle is ``wheel`` (measured as ``measured``)."""
    n = len(cmd)
    t = T * np.arange(n + 1)
    speed = speed_scale * (3.0 + 1.5 * np.sin(2 * np.pi * t / 17.0))
    yaw_rate = speed * np.tan(wheel) / (WHEELBASE + gradient * speed**2)
    yaw_rate = yaw_rate + yaw_rate_noise * np.random.default_rng(3).standard_normal(n + 1)
    yaw = np.concatenate([[0.0], np.cumsum(yaw_rate[:-1] * T)])
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(yaw[:-1]) * T)])
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(yaw[:-1]) * T)])
    seen = wheel if measured is None else measured
    obs = np.column_stack([x, y, yaw, speed, yaw_rate, np.full(n + 1, np.nan), seen])
    return TransitionDataset(
        obs=obs[:-1],
        command=np.column_stack([speed[:-1], cmd]),
        next_obs=obs[1:],
        dt=T,
        episode=np.zeros(n, dtype=int),
    )


@pytest.fixture(scope="module")
def cmd() -> np.ndarray:
    return commands(N, seed=1)


@pytest.fixture(scope="module")
def lag_wheel(cmd) -> np.ndarray:
    return wheel_angles(cmd, lag(0.158))


def _servo_warnings(model) -> list[str]:
    return [w for w in model.warnings if w.startswith("servo")]


# ---------------------------------------------------------------------------- servo structures


def test_a_first_order_lag_is_found_as_such(cmd, lag_wheel):
    model = identify(dataset(cmd, lag_wheel), VEHICLE)
    assert model.servo_structure == "lag"
    assert model.servo_time_constant == pytest.approx(0.158, rel=0.05)
    assert (model.servo_delay, model.servo_rate_limit) == (0.0, None)
    assert model.servo_fit_r2 > 0.99
    assert model.understeer_gradient == pytest.approx(GRADIENT, rel=0.05)
    assert model.warnings == ()
    # Every transition but the first history_depth ones (their commands before are unknown).
    assert model.n_samples == N - 4


def test_b_a_delay_before_the_lag_is_found(cmd):
    model = identify(dataset(cmd, wheel_angles(cmd, lag(0.1), delay=0.04)), VEHICLE)
    assert model.servo_structure.startswith("delay")
    assert model.servo_delay == pytest.approx(0.04, abs=0.01)
    assert model.servo_time_constant == pytest.approx(0.1, rel=0.2)
    assert model.warnings == ()


def test_c_a_bang_bang_rate_limited_wheel_behind_a_delay_gives_its_rate(cmd):
    """The car of the issue: 20 ms delay, then +-3.2 rad/s every 10 ms (it limit-cycles)."""
    model = identify(dataset(cmd, wheel_angles(cmd, bang_bang(3.2, 10), delay=0.02)), VEHICLE)
    assert model.warnings == ()
    assert model.servo_structure.endswith("rate")
    assert model.servo_rate_limit == pytest.approx(3.2, rel=0.15)
    assert model.servo_delay == pytest.approx(0.02, abs=0.01)
    assert model.servo_fit_r2 >= SERVO_MIN_R2


def test_c_smooth_commands_never_give_a_rate_limit_below_what_the_wheel_shows(cmd):
    """Commands too smooth to saturate the wheel: its chatter must not pass for a slow rate limit."""
    smooth = np.convolve(cmd, np.ones(16) / 16, mode="same")
    data = dataset(smooth, wheel_angles(smooth, bang_bang(3.2, 10), delay=0.02))
    model = identify(data, VEHICLE)
    fastest = float(np.max(np.abs(data.next_obs[:, 6] - data.obs[:, 6]))) / T
    assert fastest > 1.0
    assert model.servo_rate_limit is None or model.servo_rate_limit >= fastest
    assert model.servo_fit_r2 >= SERVO_MIN_R2
    assert model.warnings == ()


def test_d_a_second_order_servo_gets_a_lag_and_delay_approximation(cmd):
    model = identify(dataset(cmd, wheel_angles(cmd, second_order(25.0, 0.5))), VEHICLE)
    assert model.servo_structure in ("lag", "delay-lag")
    # The response's centre of mass is 2 zeta / wn = 0.04 s after the step.
    assert 0.02 <= model.servo_time_constant + model.servo_delay <= 0.08
    assert model.servo_fit_r2 >= SERVO_MIN_R2
    assert _servo_warnings(model) == []


def test_d_a_ringing_servo_falls_back_to_the_nominal_lag_with_a_warning(cmd):
    with pytest.warns(IdentificationWarning, match=r"servo: the best fit .* R\^2 = 0\.\d\d"):
        model = identify(dataset(cmd, wheel_angles(cmd, second_order(12.0, 0.1))), VEHICLE)
    assert model.servo_structure == "nominal"
    assert model.servo_time_constant == VEHICLE.steering.time_constant
    assert model.servo_fit_r2 < SERVO_MIN_R2
    assert len(_servo_warnings(model)) == 1
    assert model.understeer_gradient == pytest.approx(GRADIENT, rel=0.05)  # the other part stands


def test_e_a_quantised_wheel_angle_still_gives_the_lag(cmd, lag_wheel):
    measured = np.round(lag_wheel / 0.01) * 0.01
    model = identify(dataset(cmd, lag_wheel, measured=measured), VEHICLE)
    assert model.servo_time_constant == pytest.approx(0.158, rel=0.2)
    assert model.servo_delay < 0.01
    assert _servo_warnings(model) == []


def test_f_a_wheel_unrelated_to_the_command_keeps_the_nominal_servo(cmd):
    t = T * np.arange(N + 1)
    rng = np.random.default_rng(5)
    freqs, phases = rng.uniform(0.1, 1.5, 5), rng.uniform(0, 6, 5)
    wheel = np.sum(0.1 * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0)
    with pytest.warns(IdentificationWarning, match="servo"):
        model = identify(dataset(cmd, wheel), VEHICLE)
    assert model.servo_structure == "nominal"
    assert model.servo_time_constant == VEHICLE.steering.time_constant
    assert (model.servo_delay, model.servo_rate_limit) == (0.0, None)
    assert "using the nominal first-order lag of 0.158 s" in _servo_warnings(model)[0]


def test_a_wheel_that_barely_moves_keeps_the_nominal_servo(cmd):
    still = np.full(N, 0.1)
    model = _quiet_identify(dataset(still, np.full(N + 1, 0.1)))
    assert model.servo_structure == "nominal"
    assert "barely moves" in _servo_warnings(model)[0]


# ---------------------------------------------------------------------------- understeer


@pytest.mark.parametrize(
    ("gradient", "expected"),
    [(0.4, UNDERSTEER_RANGE[1]), (-0.012, -0.5 * WHEELBASE / 4.5**2)],
    ids=["understeer", "oversteer"],
)
def test_g_an_understeer_gradient_beyond_its_bound_is_held_there(cmd, lag_wheel, gradient, expected):
    with pytest.warns(IdentificationWarning, match=r"understeer: the fit gives K = .* held at"):
        model = identify(dataset(cmd, lag_wheel, gradient=gradient), VEHICLE)
    assert model.understeer_gradient == pytest.approx(expected, rel=1e-3)
    assert model.servo_structure == "lag"  # the servo fit does not care


def test_a_poor_understeer_fit_gives_the_kinematic_model(cmd, lag_wheel):
    model = _quiet_identify(dataset(cmd, lag_wheel, yaw_rate_noise=1.5))
    assert model.understeer_gradient == 0.0
    assert model.understeer_fit_r2 < 0.3
    assert any(w.startswith("understeer") and "R^2" in w for w in model.warnings)


def test_a_slow_car_gives_the_kinematic_model_without_raising(cmd, lag_wheel):
    model = _quiet_identify(dataset(cmd, lag_wheel, speed_scale=0.2))  # below min_speed = 1 m/s
    assert model.understeer_gradient == 0.0
    assert math.isnan(model.understeer_fit_r2)
    assert any("faster than 1 m/s" in w for w in model.warnings)
    assert model.servo_structure == "lag"


# ---------------------------------------------------------------------------- errors and data


def test_too_few_transitions_raise(cmd, lag_wheel):
    data = dataset(cmd[:23], lag_wheel[:24])  # 23 transitions, 4 of them without history
    with pytest.raises(ParameterError, match=r"at least 20 transitions .* got 19"):
        identify(data, VEHICLE)


def test_no_measured_wheel_angle_raises(cmd, lag_wheel):
    with pytest.raises(ParameterError, match="finite wheel angle"):
        identify(dataset(cmd, lag_wheel, measured=np.full(N + 1, np.nan)), VEHICLE)


def test_command_history_stops_at_episode_starts():
    u = np.arange(6.0)
    hist = command_history(u, np.array([0, 0, 0, 1, 1, 1]), depth=2)
    np.testing.assert_array_equal(hist[:, 0], u)
    np.testing.assert_array_equal(hist[:, 1], [np.nan, 0, 1, np.nan, 3, 4])
    np.testing.assert_array_equal(hist[:, 2], [np.nan, np.nan, 0, np.nan, np.nan, 3])


def _quiet_identify(data: TransitionDataset):
    with pytest.warns(IdentificationWarning):
        return identify(data, VEHICLE)


def test_25_noisy_samples_never_give_an_implausible_servo(cmd, lag_wheel):
    # Issue 13: 25 samples once wrote a time constant of 1.4e7 s with R^2 = -0.017.
    n = 25
    noisy = lag_wheel[: n + 1] + 0.02 * np.random.default_rng(7).standard_normal(n + 1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = identify(dataset(cmd[:n], lag_wheel[: n + 1], measured=noisy), VEHICLE)
    assert TIME_CONSTANT_RANGE[0] <= model.servo_time_constant <= 1.0
    if model.servo_structure == "nominal":
        assert model.servo_time_constant == VEHICLE.steering.time_constant
        assert any("servo" in str(w.message) for w in caught)
    else:
        assert model.servo_fit_r2 >= SERVO_MIN_R2
