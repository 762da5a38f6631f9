"""Tests of the paper's kinematic bicycle model and its linearisation (Eq. 1-3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.kinematic import kinematic_rhs, kinematic_step, linearize_discrete

WHEELBASE = 0.307
DT = 0.05


def euler_map(state: np.ndarray, u: np.ndarray) -> np.ndarray:
    return state + DT * kinematic_rhs(state, u, WHEELBASE)


def central_jacobians(state: np.ndarray, u: np.ndarray, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    a_fd = np.zeros((3, 3))
    b_fd = np.zeros((3, 2))
    for j in range(3):
        e = np.zeros(3)
        e[j] = eps
        a_fd[:, j] = (euler_map(state + e, u) - euler_map(state - e, u)) / (2 * eps)
    for j in range(2):
        e = np.zeros(2)
        e[j] = eps
        b_fd[:, j] = (euler_map(state, u + e) - euler_map(state, u - e)) / (2 * eps)
    return a_fd, b_fd


def test_rhs_values() -> None:
    rhs = kinematic_rhs([1.0, 2.0, math.pi / 2], [2.0, 0.1], WHEELBASE)
    np.testing.assert_allclose(rhs, [0.0, 2.0, 2.0 * math.tan(0.1) / WHEELBASE], atol=1e-15)


def test_linearization_matches_finite_differences() -> None:
    rng = np.random.default_rng(0)
    n = 8
    theta = rng.uniform(-math.pi, math.pi, n)
    speed = rng.uniform(0.0, 8.0, n)
    steer = rng.uniform(-0.4, 0.4, n)
    a_mat, b_mat = linearize_discrete(theta, speed, steer, WHEELBASE, DT)
    assert a_mat.shape == (n, 3, 3)
    assert b_mat.shape == (n, 3, 2)
    for k in range(n):
        state = np.array([rng.normal(), rng.normal(), theta[k]])
        a_fd, b_fd = central_jacobians(state, np.array([speed[k], steer[k]]))
        np.testing.assert_allclose(a_mat[k], a_fd, atol=1e-7)
        np.testing.assert_allclose(b_mat[k], b_fd, atol=1e-7)


def test_linearization_matches_paper_entries() -> None:
    theta, speed, steer = 0.3, 2.0, 0.2
    a_mat, b_mat = linearize_discrete(theta, speed, steer, WHEELBASE, DT)
    assert a_mat.shape == (3, 3)
    assert b_mat.shape == (3, 2)
    expected_a = [[1, 0, -speed * math.sin(theta) * DT], [0, 1, speed * math.cos(theta) * DT], [0, 0, 1]]
    expected_b = [
        [math.cos(theta) * DT, 0],
        [math.sin(theta) * DT, 0],
        [math.tan(steer) * DT / WHEELBASE, speed * DT / (WHEELBASE * math.cos(steer) ** 2)],
    ]
    np.testing.assert_allclose(a_mat, expected_a, rtol=1e-14)
    np.testing.assert_allclose(b_mat, expected_b, rtol=1e-14)


def test_linearization_broadcasts_scalars_against_arrays() -> None:
    a_mat, b_mat = linearize_discrete(np.zeros(4), 2.0, 0.1, WHEELBASE, DT)
    assert a_mat.shape == (4, 3, 3)
    np.testing.assert_allclose(b_mat[0], b_mat[3])


def test_one_step_prediction_is_second_order_accurate() -> None:
    state_r = np.array([1.0, -0.5, 0.7])
    u_r = np.array([3.0, 0.15])
    a_mat, b_mat = linearize_discrete(state_r[2], u_r[0], u_r[1], WHEELBASE, DT)
    direction_x = np.array([0.3, -0.2, 1.0])
    direction_u = np.array([0.5, -1.0])

    def errors(eps: float) -> tuple[float, float]:
        xi, du = eps * direction_x, eps * direction_u
        linear = a_mat @ xi + b_mat @ du
        euler = euler_map(state_r + xi, u_r + du) - euler_map(state_r, u_r)
        exact = kinematic_step(state_r + xi, u_r + du, WHEELBASE, DT) - kinematic_step(
            state_r, u_r, WHEELBASE, DT
        )
        return float(np.linalg.norm(euler - linear)), float(np.linalg.norm(exact - linear))

    e1, x1 = errors(1e-2)
    e2, x2 = errors(5e-3)
    # Halving the perturbation quarters the linearisation error of the Euler map.
    assert e2 / e1 == pytest.approx(0.25, rel=0.05)
    # Against the exact step the error is O(eps^2) plus O(eps * dt^2) from the discretisation.
    scale = 1e-2
    assert x1 < 2.0 * e1 + 5.0 * scale * DT**2 * u_r[0] / WHEELBASE
    assert x2 < x1


def test_kinematic_step_is_exact_arc() -> None:
    state = np.array([0.2, -0.1, 0.4])
    u = np.array([2.5, -0.3])
    result = solve_ivp(
        lambda _t, s: kinematic_rhs(s, u, WHEELBASE), (0.0, 0.4), state, rtol=1e-11, atol=1e-12
    )
    np.testing.assert_allclose(kinematic_step(state, u, WHEELBASE, 0.4), result.y[:, -1], atol=1e-8)
    straight = kinematic_step(state, [2.0, 0.0], WHEELBASE, 0.5)
    np.testing.assert_allclose(straight, [0.2 + math.cos(0.4), -0.1 + math.sin(0.4), 0.4], atol=1e-14)


def test_kinematic_full_circle_returns_to_start() -> None:
    steer = 0.2
    radius = WHEELBASE / math.tan(steer)
    period = 2 * math.pi * radius / 1.5
    state = np.array([0.0, 0.0, 0.0])
    for _ in range(100):
        state = kinematic_step(state, [1.5, steer], WHEELBASE, period / 100)
    np.testing.assert_allclose(state[:2], [0.0, 0.0], atol=1e-10)
    assert state[2] == pytest.approx(2 * math.pi)


def test_bad_inputs_raise() -> None:
    with pytest.raises(ParameterError):
        kinematic_rhs([0, 0, 0], [1, 0], 0.0)
    with pytest.raises(ParameterError):
        kinematic_step([0, 0, 0], [1, 0], WHEELBASE, -0.1)
    with pytest.raises(ValueError, match="shape"):
        kinematic_rhs([0, 0], [1, 0], WHEELBASE)
    with pytest.raises(ValueError, match="1-D"):
        linearize_discrete(np.zeros((2, 2)), 1.0, 0.0, WHEELBASE, DT)
