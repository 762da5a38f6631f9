"""identify() on simulated steering actuators: with and without a wheel-angle sensor, chosen on held-out data.

The synthetic car (``ident_synthetic``): an actuator at 1 ms behind a delay, a kinematic car with
understeer gradient 0.01 s^2/m, 600 transitions at 0.05 s. The nominal car is the f1tenth preset
(lag 0.158 s, 3.2 rad/s, K = 0).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from ident_synthetic import (
    GRADIENT,
    VEHICLE,
    bang_bang,
    commands,
    dataset,
    lag,
    second_order,
    unmeasured,
    wheel_angles,
)

from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.learning.identification import (
    UNDERSTEER_RANGE,
    command_history,
    identify,
    predicted_yaw_rate,
)
from rkmpc.learning.servo_model import RATE_LIMIT_FACTOR

N = 600
NOMINAL_TAU = VEHICLE.steering.time_constant


@pytest.fixture(scope="module")
def cmd() -> np.ndarray:
    return commands(N, seed=1)


def quiet(data, **options):
    """identify(), its warnings recorded: (model, [warning messages])."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = identify(data, VEHICLE, **options)
    said = [str(w.message) for w in caught if issubclass(w.category, IdentificationWarning)]
    assert said == list(model.warnings)  # every warning is in the model, and the reverse
    return model, said


def assert_nominal(model) -> None:
    assert model.status == "nominal" and model.status_reason
    assert (model.servo_structure, model.servo_time_constant) == ("nominal", NOMINAL_TAU)
    assert (model.servo_delay, model.servo_rate_limit, model.understeer_gradient) == (0.0, None, 0.0)
    assert any("marked nominal" in w for w in model.warnings)


# ---------------------------------------------------------------------------- with a wheel-angle sensor


def test_a_lag_faster_than_nominal_is_found_and_beats_the_nominal_model(cmd):
    model, said = quiet(dataset(cmd, wheel_angles(cmd, lag(0.08))))
    assert (model.status, model.fitted_on, model.servo_structure) == ("identified", "steer_angle", "lag")
    assert model.servo_time_constant == pytest.approx(0.08, rel=0.05)
    assert (model.servo_delay, model.servo_rate_limit) == (0.0, None)
    assert model.understeer_gradient == pytest.approx(GRADIENT, rel=0.05)
    assert said == []
    # Held out: far better than the nominal model, on the wheel angle and on the yaw rate.
    assert model.wheel_heldout_rmse < 0.2 * model.wheel_nominal_rmse
    assert model.error_ratio < 0.2 and model.heldout_r2 > 0.99
    assert model.folds == 5 and model.n_samples == N
    assert dict(model.heldout_candidates)["nominal"] == pytest.approx(model.wheel_nominal_rmse)


def test_a_delay_before_the_lag_is_found(cmd):
    model, _ = quiet(dataset(cmd, wheel_angles(cmd, lag(0.1), delay=0.04)))
    assert model.servo_structure == "delay-lag"
    assert model.servo_delay == pytest.approx(0.04, abs=0.01)
    assert model.servo_time_constant == pytest.approx(0.1, rel=0.2)


def test_a_bang_bang_wheel_behind_a_delay_is_never_given_an_implausible_rate(cmd):
    """The F1TENTH gym's servo: 20 ms delay, then +-3.2 rad/s every 10 ms (it limit-cycles)."""
    model, _ = quiet(dataset(cmd, wheel_angles(cmd, bang_bang(3.2, 10), delay=0.02)))
    assert model.status == "identified"
    # Never a rate limit far below the wheel's (the 0.64 rad/s), and fast as the gym's wheel.
    assert model.servo_rate_limit is None or model.servo_rate_limit >= 3.2 / 1.5
    assert model.servo_delay + model.servo_time_constant <= 0.08
    assert model.wheel_heldout_rmse < 0.5 * model.wheel_nominal_rmse


def test_a_second_order_servo_gets_a_delay_and_lag_near_its_centre_of_mass(cmd):
    model, _ = quiet(dataset(cmd, wheel_angles(cmd, second_order(25.0, 0.5))))
    # The response's centre of mass is 2 zeta / wn = 0.04 s after the step.
    assert 0.02 <= model.servo_time_constant + model.servo_delay <= 0.08
    assert model.wheel_heldout_rmse < 0.5 * model.wheel_nominal_rmse


def test_the_nominal_car_is_marked_nominal_loudly(cmd):
    """The car is the nominal one (lag 0.158 s, 3.2 rad/s, K = 0): nothing predicts better."""
    model, said = quiet(dataset(cmd, wheel_angles(cmd, lag(NOMINAL_TAU)), gradient=0.0))
    assert_nominal(model)
    assert "neither the servo nor the understeer gradient" in model.status_reason
    assert said[-1].startswith("identification: ") and "the model is marked nominal" in said[-1]


def test_a_wheel_unrelated_to_the_command_keeps_the_nominal_servo(cmd):
    t = 0.05 * np.arange(N + 1)
    rng = np.random.default_rng(5)
    freqs, phases = rng.uniform(0.1, 1.5, 5), rng.uniform(0, 6, 5)
    wheel = np.sum(0.1 * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0)
    model, said = quiet(dataset(cmd, wheel))
    assert model.servo_structure == "nominal"
    assert any(w.startswith("servo: no plausible candidate predicts the held-out wheel angle") for w in said)
    assert model.understeer_gradient == pytest.approx(GRADIENT, rel=0.05)  # the other part stands


def test_a_wheel_that_barely_moves_keeps_the_nominal_servo():
    model, said = quiet(dataset(np.full(N, 0.1), np.full(N + 1, 0.1)))
    assert model.servo_structure == "nominal"
    assert said[0].startswith("servo: the wheel angle barely moves")


def test_a_quantised_wheel_angle_still_gives_the_lag(cmd):
    wheel = wheel_angles(cmd, lag(0.25, 2.0))  # the zoo's cheap servo
    model, _ = quiet(dataset(cmd, wheel, measured=np.round(wheel / 0.01) * 0.01))
    assert model.servo_time_constant == pytest.approx(0.25, rel=0.1)
    assert model.servo_delay < 0.01


# ---------------------------------------------------------------------------- understeer


@pytest.mark.parametrize(
    ("gradient", "expected"),
    [(0.4, UNDERSTEER_RANGE[1]), (-0.012, -0.5 * 0.307 / 4.5**2)],
    ids=["understeer", "oversteer"],
)
def test_an_understeer_gradient_beyond_its_bound_is_held_there(cmd, gradient, expected):
    model, said = quiet(dataset(cmd, wheel_angles(cmd, lag(0.08)), gradient=gradient))
    assert model.understeer_gradient == pytest.approx(expected, rel=1e-3)
    assert any(w.startswith("understeer: the fit gives K beyond the plausible") for w in said)


def test_a_noisy_yaw_rate_gives_the_kinematic_model(cmd):
    model, said = quiet(dataset(cmd, wheel_angles(cmd, lag(0.08)), yaw_rate_noise=1.5))
    assert model.understeer_gradient == 0.0
    assert any(
        w.startswith("understeer: no plausible candidate predicts the held-out yaw rate") for w in said
    )
    assert model.servo_structure == "lag"  # the servo does not care


def test_a_slow_car_gives_the_kinematic_model_without_raising(cmd):
    model, said = quiet(dataset(cmd, wheel_angles(cmd, lag(0.08)), speed_scale=0.2))  # below 1 m/s
    assert model.understeer_gradient == 0.0 and math.isnan(model.understeer_fit_r2)
    assert any("faster than the minimum speed" in w for w in said)
    assert model.servo_structure == "lag" and math.isnan(model.heldout_rmse)


# ---------------------------------------------------------------------------- without a wheel-angle sensor


def test_without_a_wheel_angle_the_servo_and_k_come_from_the_yaw_rate(cmd):
    data = unmeasured(dataset(cmd, wheel_angles(cmd, lag(0.1), delay=0.05)))
    model, said = quiet(data)
    assert (model.status, model.fitted_on) == ("identified", "yaw_rate")
    assert model.servo_structure == "delay-lag"
    assert model.servo_delay == pytest.approx(0.05, abs=0.0125)
    assert model.servo_time_constant == pytest.approx(0.1, rel=0.15)
    assert model.understeer_gradient == pytest.approx(GRADIENT, rel=0.1)
    assert said == []
    # Honest figures: held out, against the yaw rate measured, never the model's own output.
    assert model.error_ratio < 0.2 and model.heldout_r2 > 0.98
    assert math.isnan(model.wheel_heldout_rmse)
    names = dict(model.heldout_candidates)
    assert names["nominal"] == pytest.approx(model.nominal_rmse)
    assert names["delay-lag + K"] == pytest.approx(model.heldout_rmse)
    # The model predicts the yaw rate of data it never saw (other commands) better than nominal.
    other = commands(N, seed=2)
    unseen = unmeasured(dataset(other, wheel_angles(other, lag(0.1), delay=0.05)))
    nominal, _ = quiet(unmeasured(dataset(cmd, wheel_angles(cmd, lag(NOMINAL_TAU)), gradient=0.0)))
    fitted, measured = predicted_yaw_rate(model, unseen, VEHICLE)
    plain, _ = predicted_yaw_rate(nominal, unseen, VEHICLE)
    assert np.sqrt(np.mean((fitted - measured) ** 2)) < 0.2 * np.sqrt(np.mean((plain - measured) ** 2))


def test_without_a_wheel_angle_the_nominal_car_is_marked_nominal(cmd):
    model, _ = quiet(unmeasured(dataset(cmd, wheel_angles(cmd, lag(NOMINAL_TAU)), gradient=0.0)))
    assert_nominal(model)
    assert model.fitted_on == "yaw_rate"
    assert model.status_reason.startswith("no plausible candidate predicts the held-out yaw rate clearly")
    assert model.heldout_rmse == model.nominal_rmse and model.error_ratio == 1.0


def test_a_yaw_rate_unrelated_to_the_commands_is_marked_nominal(cmd):
    other = commands(N, seed=9)
    data = dataset(cmd, wheel_angles(other, lag(0.08)), measured=np.full(N + 1, np.nan))
    model, _ = quiet(data)
    assert_nominal(model)


def test_commands_that_barely_move_keep_the_nominal_servo():
    data = unmeasured(dataset(np.full(N, 0.1), np.full(N + 1, 0.1)))
    model, said = quiet(data)
    assert model.servo_structure == "nominal"
    assert said[0].startswith("servo: the steering command barely moves")


def test_the_gym_servo_without_a_wheel_angle_is_near_its_own(cmd):
    """20 ms delay, +-3.2 rad/s: never a 5 ms lag nor a rate limit far below 3.2 rad/s."""
    model, _ = quiet(unmeasured(dataset(cmd, wheel_angles(cmd, bang_bang(3.2, 10), delay=0.02))))
    assert model.status == "identified"
    assert model.servo_rate_limit is None or 3.2 / 1.5 <= model.servo_rate_limit <= 3.2 * 1.5
    assert model.servo_time_constant >= 0.02  # 0.4 periods: what data at 20 Hz resolve
    assert 0.0 <= model.servo_delay <= 0.05 and model.servo_delay + model.servo_time_constant <= 0.08


# ---------------------------------------------------------------------------- the source and errors


def test_the_yaw_rate_can_be_chosen_although_a_wheel_angle_is_measured(cmd):
    model, _ = quiet(dataset(cmd, wheel_angles(cmd, lag(0.08))), source="yaw_rate")
    assert model.fitted_on == "yaw_rate" and math.isnan(model.wheel_heldout_rmse)
    assert model.servo_time_constant == pytest.approx(0.08, rel=0.15)


def test_neither_a_wheel_angle_nor_a_yaw_rate_raises(cmd):
    data = dataset(cmd, wheel_angles(cmd, lag(0.08)), measured=np.full(N + 1, np.nan))
    obs, nxt = data.obs.copy(), data.next_obs.copy()
    obs[:, 4] = nxt[:, 4] = np.nan
    blind = type(data)(obs, data.command, nxt, data.dt, data.episode)
    with pytest.raises(
        ParameterError, match=r"at least 20 transitions with a yaw rate .* got 0 \(0 with a wheel"
    ):
        identify(blind, VEHICLE)
    with pytest.raises(ParameterError, match="with a finite wheel angle before and after"):
        identify(blind, VEHICLE, source="steer_angle")


def test_too_few_transitions_raise_and_few_are_marked_nominal(cmd):
    wheel = wheel_angles(cmd, lag(0.08))
    with pytest.raises(ParameterError, match=r"at least 20 transitions .* got 12 \(19 with a wheel angle"):
        identify(dataset(cmd[:19], wheel[:20]), VEHICLE)
    with pytest.raises(ParameterError, match=r"yaw rate at more than 1 m/s after the first 7 .* got 19"):
        identify(unmeasured(dataset(cmd[:26], wheel[:27])), VEHICLE)  # 26 transitions, 7 burnt in
    model, _ = quiet(dataset(cmd[:25], wheel[:26]))
    assert_nominal(model)
    assert model.status_reason.startswith("too few transitions (25) for two held-out blocks")


@pytest.mark.parametrize(
    ("option", "value"),
    [("folds", 1), ("folds", 2.5), ("source", "gps"), ("min_speed", -1.0), ("min_speed", None)],
)
def test_bad_options_are_refused(cmd, option, value):
    with pytest.raises(ParameterError, match=rf"identify: {option} must be"):
        identify(dataset(cmd, wheel_angles(cmd, lag(0.08))), VEHICLE, **{option: value})


def test_command_history_stops_at_episode_starts():
    u = np.arange(6.0)
    hist = command_history(u, np.array([0, 0, 0, 1, 1, 1]), depth=2)
    np.testing.assert_array_equal(hist[:, 0], u)
    np.testing.assert_array_equal(hist[:, 1], [np.nan, 0, 1, np.nan, 3, 4])
    np.testing.assert_array_equal(hist[:, 2], [np.nan, np.nan, 0, np.nan, np.nan, 3])


def test_the_identified_servo_never_leaves_its_plausible_range(cmd):
    # Issue 13: 25 noisy samples once wrote a time constant of 1.4e7 s with R^2 = -0.017.
    wheel = wheel_angles(cmd, lag(0.08))
    noisy = wheel[:41] + 0.02 * np.random.default_rng(7).standard_normal(41)
    model, _ = quiet(dataset(cmd[:40], wheel[:41], measured=noisy))
    assert 0.02 <= model.servo_time_constant <= 1.0
    rate = VEHICLE.steering.max_rate
    assert model.servo_rate_limit is None or rate / RATE_LIMIT_FACTOR <= model.servo_rate_limit <= rate * 3


def test_rkmpc_train_says_loudly_that_a_model_is_marked_nominal(cmd, tmp_path, capsys):
    from rkmpc.cli import main
    from rkmpc.learning.io import load_identified

    data = unmeasured(dataset(cmd, wheel_angles(cmd, lag(NOMINAL_TAU)), gradient=0.0))
    path, out = tmp_path / "nominal.npz", tmp_path / "id.json"
    data.save(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["train", "--data", str(path), "--kind", "identified", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("identified servo nominal: tau 0.158 s; understeer K 0.0000 s^2/m")
    assert "fitted on the yaw rate" in lines[0]
    assert lines[1].startswith("status nominal (5 time blocks): held-out yaw rate ")
    assert lines[2].startswith("MARKED NOMINAL: no plausible candidate predicts the held-out yaw rate")
    model = load_identified(out)
    assert model.status == "nominal" and lines[2] == f"MARKED NOMINAL: {model.status_reason}"
