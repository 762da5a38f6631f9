"""The servo model of identification: exact one-period steps, the discretisation lmpc-id uses, the fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.learning.servo_fit import (
    MAX_DELAY,
    SERVO_PARAMETERS,
    SERVO_STRUCTURES,
    delay_periods,
    fit_servo,
    history_depth,
    lag_delay_weights,
    servo_step,
)

T = 0.05


def _history(n: int, depth: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.4, 0.4, size=(n, depth + 1))


def _fine(delta: float, commands: np.ndarray, delay: float, tau: float, rate: float) -> float:
    """One period of the servo by explicit Euler at 10 microseconds."""
    h = 1e-5
    for i in range(round(T / h)):
        t = (i + 0.5) * h
        # The command in force at t - delay: u_{k-j} covers [-j T, -(j - 1) T).
        j = math.floor((delay - t) / T) + 1
        u = commands[j]
        delta += h * min(max((u - delta) / tau, -rate), rate)
    return delta


@pytest.mark.parametrize(
    ("delay", "tau", "rate"),
    [(0.0, 0.1, math.inf), (0.03, 0.05, 2.0), (0.07, 0.02, 1.0), (0.1, 0.005, 3.2), (MAX_DELAY, 0.2, 0.5)],
)
def test_servo_step_is_the_exact_solution_over_one_period(delay, tau, rate):
    hist = _history(4, history_depth(T), seed=1)
    delta = np.array([0.0, 0.3, -0.2, 0.05])
    exact = servo_step(delta, hist, T, delay, tau, rate)
    fine = [_fine(float(d), row, delay, tau, rate) for d, row in zip(delta, hist, strict=True)]
    np.testing.assert_allclose(exact, fine, atol=2e-4)


@pytest.mark.parametrize("delay", [0.0, 0.02, 0.05, 0.07, 0.1, 0.149])
def test_without_rate_limit_the_step_is_the_linear_discretisation(delay):
    hist = _history(50, history_depth(T))
    delta = np.linspace(-0.3, 0.3, 50)
    a, w = lag_delay_weights(0.08, delay, T)
    linear = a * delta + hist[:, : len(w)] @ w
    np.testing.assert_allclose(servo_step(delta, hist, T, delay, 0.08, math.inf), linear, atol=1e-12)
    assert a == pytest.approx(math.exp(-T / 0.08))
    assert w.sum() == pytest.approx(1.0 - a)
    m = delay_periods(delay, T)
    assert np.all(w[:m] == 0.0) and w[m] > 0.0
    assert len(w) == m + (1 if delay == m * T else 2)


def test_lag_delay_weights_without_delay_is_the_plain_lag():
    a, w = lag_delay_weights(0.158, 0.0, T)
    assert a == math.exp(-T / 0.158)
    np.testing.assert_array_equal(w, [1.0 - a])


def test_many_parameter_sets_at_once_match_one_by_one():
    hist = _history(30, history_depth(T))
    delta = np.linspace(-0.2, 0.2, 30)
    delays, taus, rates = (
        np.array([0.0, 0.06, 0.12]),
        np.array([0.01, 0.1, 0.5]),
        np.array([1.0, np.inf, 5.0]),
    )
    batch = servo_step(delta, hist, T, delays, taus, rates)
    assert batch.shape == (3, 30)
    for g in range(3):
        np.testing.assert_array_equal(batch[g], servo_step(delta, hist, T, delays[g], taus[g], rates[g]))


def test_the_structure_table_names_known_parameters_once():
    names = [s.name for s in SERVO_STRUCTURES]
    assert len(set(names)) == len(names) and names[0] == "lag"
    for s in SERVO_STRUCTURES:
        assert set(s.fitted) <= set(SERVO_PARAMETERS) and len(set(s.fitted)) == len(s.fitted)
    assert history_depth(T) == 7  # u_{k-1} .. u_{k-7}: a delay of up to 0.3 s plus its remainder


def test_fit_servo_ranks_every_structure_and_flags_implausible_bounds():
    rng = np.random.default_rng(2)
    hist = _history(400, history_depth(T), seed=3)
    delta = rng.uniform(-0.3, 0.3, 400)
    # The wheel barely follows the command: every lag ends at its upper bound of 1 s.
    nxt = servo_step(delta, hist, T, 0.0, 5.0, math.inf)
    fits = fit_servo(delta, nxt, hist, T)
    assert sorted(f.structure for f in fits) == sorted(s.name for s in SERVO_STRUCTURES)
    assert [f.bic for f in fits] == sorted(f.bic for f in fits)
    lag = next(f for f in fits if f.structure == "lag")
    assert lag.time_constant == pytest.approx(1.0)
    assert lag.at_bound == ("time_constant at its upper bound 1 s",)
