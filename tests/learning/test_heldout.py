"""The pieces of held-out identification: time blocks, the choice, the servo run from commands, K's fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.learning.heldout import MIN_BLOCK, Score, choose, heldout_r2, time_blocks
from rkmpc.learning.servo_model import (
    MAX_DELAY,
    RATE_LIMIT_FACTOR,
    history_depth,
    refine,
    servo_step,
    simulate_servo,
    vehicle_servo_parameters,
)
from rkmpc.learning.understeer import fit_gradients, gradient_bounds, yaw_rate_of

T = 0.05


# ---------------------------------------------------------------------------- time blocks


def test_blocks_are_contiguous_cover_the_usable_samples_and_fits_keep_a_gap():
    usable = np.ones(200, dtype=bool)
    usable[50:60] = False
    folds = time_blocks(usable, 5, gap=4)
    assert folds is not None and folds.count == 5
    assert folds.train.shape == (6, 200) and folds.test.shape == (5, 200)
    # Every usable sample is held out exactly once, in one contiguous run of usable samples.
    np.testing.assert_array_equal(folds.test.sum(axis=0), usable.astype(int))
    for f in range(5):
        index = np.flatnonzero(folds.test[f])
        assert np.all(usable[index[0] : index[-1] + 1] <= folds.test[f, index[0] : index[-1] + 1])
        # Its fit never sees it, nor the gap around it, nor an unusable sample.
        lo, hi = max(index[0] - 4, 0), min(index[-1] + 5, 200)
        assert not folds.train[f, lo:hi].any()
        assert not (folds.train[f] & ~usable).any()
        assert folds.train[f].sum() == usable.sum() - (hi - lo) + (~usable[lo:hi]).sum()
    np.testing.assert_array_equal(folds.train[-1], usable)  # the final fit: every usable sample
    restricted = folds.restricted(np.arange(200) % 2 == 0)
    assert not restricted.test[:, 1::2].any() and restricted.test[:, ::2].sum() == folds.test[:, ::2].sum()


def test_too_few_samples_make_no_blocks():
    assert time_blocks(np.ones(2 * MIN_BLOCK - 1, dtype=bool), 5, gap=0) is None
    assert time_blocks(np.ones(25, dtype=bool), 5, gap=10) is None  # the fits would see < 10 samples
    folds = time_blocks(np.ones(35, dtype=bool), 5, gap=0)
    assert folds is not None and folds.count == 3  # fewer blocks, none under MIN_BLOCK


# ---------------------------------------------------------------------------- the choice


def _score(name: str, mse: float, parameters: int, nonlinear: bool = False) -> Score:
    return Score(name, parameters, np.array([mse * 50, mse * 50]), np.array([50, 50]), nonlinear)


def test_a_candidate_must_beat_the_nominal_model_by_the_margin():
    nominal = _score("nominal", 1.0, 0)
    assert choose([nominal, _score("lag", 0.97, 1)], nominal) is nominal
    better = _score("lag", 0.9, 1)
    assert choose([nominal, better], nominal) is better
    assert choose([nominal, _score("lag", math.nan, 1)], nominal) is nominal


def test_the_simplest_of_the_candidates_that_predict_alike_is_kept():
    nominal = _score("nominal", 1.0, 0)
    lag, delay_lag = _score("lag", 0.50, 1), _score("delay-lag", 0.49, 2)
    assert choose([nominal, delay_lag, lag], nominal) is lag
    much_better = _score("delay-lag", 0.40, 2)
    assert choose([nominal, lag, much_better], nominal) is much_better
    # Of two with as many parameters that predict alike, the one without a rate limit.
    rate = _score("delay-rate", 0.399, 2, nonlinear=True)
    assert choose([nominal, rate, much_better], nominal) is much_better


def test_heldout_r2_is_against_each_blocks_own_mean():
    usable = np.ones(40, dtype=bool)
    folds = time_blocks(usable, 2, gap=0)
    assert folds is not None
    y = np.concatenate([np.full(20, 5.0), np.full(20, -5.0)]) + np.tile([0.1, -0.1], 20)
    perfect = Score("x", 1, np.zeros(2), np.array([20, 20]))
    assert heldout_r2(perfect, y, folds) == 1.0
    means = Score("x", 1, np.array([20 * 0.01, 20 * 0.01]), np.array([20, 20]))  # each block's mean
    assert heldout_r2(means, y, folds) == pytest.approx(0.0)


# ---------------------------------------------------------------------------- the servo run from commands


def _history(u: np.ndarray, depth: int) -> np.ndarray:
    out = np.full((len(u), depth + 1), u[0])
    for j in range(depth + 1):
        out[j:, j] = u[: len(u) - j]
    return out


def test_simulating_is_stepping_the_exact_one_period_servo_from_its_own_output():
    rng = np.random.default_rng(0)
    u = np.clip(np.cumsum(rng.normal(0.0, 0.08, 120)), -0.4, 0.4)
    hist = _history(u, history_depth(T))
    starts = np.zeros(120, dtype=bool)
    starts[[0, 70]] = True
    initial = np.where(starts, 0.2, np.nan)
    delay, tau, rate = (
        np.array([0.0, 0.07, MAX_DELAY]),
        np.array([0.02, 0.1, 0.3]),
        np.array([np.inf, 1.5, 4.0]),
    )
    wheel = simulate_servo(hist, starts, initial, T, delay, tau, rate)
    assert wheel.shape == (3, 120)
    for g in range(3):
        delta = 0.0
        for k in range(120):
            delta = 0.2 if starts[k] else delta
            delta = float(servo_step(np.array([delta]), hist[k : k + 1], T, delay[g], tau[g], rate[g])[0])
            assert wheel[g, k] == pytest.approx(delta, abs=1e-12)


def test_the_plausible_servo_of_a_car_is_relative_to_its_data_sheet():
    space = vehicle_servo_parameters(3.2, T)
    rate = space["rate_limit"]
    assert (rate.lower, rate.upper, rate.neutral) == pytest.approx((3.2 / RATE_LIMIT_FACTOR, 9.6, 3.2))
    assert not rate.lower_is_a_result  # a rate limit at 1.07 rad/s is a fit of something else
    assert space["time_constant"].lower == pytest.approx(0.02) and space["time_constant"].lower_is_a_result
    assert space["delay"].upper == MAX_DELAY == 0.3
    assert space["delay"].value(np.linspace(0, 1, space["delay"].grid))[1] == pytest.approx(T / 2)


def test_refine_is_never_worse_than_its_start_and_finds_a_smooth_minimum():
    def objective(z: np.ndarray) -> np.ndarray:
        return np.sum((z - np.array([0.33, 0.71])) ** 2, axis=1)

    z, value = refine(objective, np.array([0.3, 0.7]), np.array([0.1, 0.1]))
    assert value <= float(objective(np.array([[0.3, 0.7]]))[0])
    np.testing.assert_allclose(z, [0.33, 0.71], atol=0.01)


# ---------------------------------------------------------------------------- K


def test_fit_gradients_recovers_k_under_each_weighting_and_holds_it_in_its_bounds():
    rng = np.random.default_rng(1)
    speed = rng.uniform(1.5, 4.0, 300)
    wheel = rng.uniform(-0.3, 0.3, (2, 300))
    yaw_rate = yaw_rate_of(np.tan(wheel[0]), speed, 0.307, 0.012)
    weights = np.zeros((3, 300))
    weights[0, :150], weights[1, 150:], weights[2] = 1.0, 1.0, 1.0
    bounds = gradient_bounds(0.307, 4.0)
    k = fit_gradients(np.tan(wheel), speed, yaw_rate, weights, 0.307, bounds)
    assert k.shape == (2, 3)
    np.testing.assert_allclose(k[0], 0.012, rtol=1e-9)  # the wheel that made the yaw rate: exact
    assert np.all((bounds[0] <= k[1]) & (k[1] <= bounds[1]))
    huge = yaw_rate_of(np.tan(wheel[0]), speed, 0.307, 0.5)
    assert fit_gradients(np.tan(wheel[:1]), speed, huge, weights, 0.307, bounds)[0, 0] == bounds[1]
    assert bounds[0] == pytest.approx(-0.5 * 0.307 / 16.0)
    # No cornering under a weighting: K = 0.
    assert fit_gradients(np.tan(wheel[:1]), speed, 0.0 * yaw_rate, weights, 0.307, bounds)[0, 0] == 0.0
