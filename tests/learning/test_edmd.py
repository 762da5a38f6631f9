"""Closed-form least squares: exact recovery of known linear systems."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.learning.koopman.edmd import fit_dynamics, fit_output, ridge_lstsq
from rkmpc.learning.koopman.lifting import RBFLifting
from rkmpc.learning.koopman.model import KoopmanModel


def _linear_system(seed: int = 0, nx: int = 4, nu: int = 2, n_traj: int = 20, steps: int = 30):
    """Trajectories of x+ = A x + B u with a random stable A; returns truth and one-step data."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(nx, nx))
    A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))  # spectral radius 0.9
    B = rng.normal(size=(nx, nu))
    X, U, Xn = [], [], []
    for _ in range(n_traj):
        x = rng.normal(size=nx)
        for _ in range(steps):
            u = rng.uniform(-1, 1, size=nu)
            xn = A @ x + B @ u
            X.append(x)
            U.append(u)
            Xn.append(xn)
            x = xn
    return A, B, np.array(X), np.array(U), np.array(Xn)


def test_identity_lifting_recovers_the_system_exactly():
    A, B, X, U, Xn = _linear_system()
    A_hat, B_hat = fit_dynamics(X, U, Xn)
    assert A_hat.shape == (4, 4) and B_hat.shape == (4, 2)
    np.testing.assert_allclose(A_hat, A, rtol=0, atol=1e-9)
    np.testing.assert_allclose(B_hat, B, rtol=0, atol=1e-9)


def test_state_rows_are_exact_with_extra_features():
    A, B, X, U, Xn = _linear_system(seed=1)

    def lift(x):
        return np.hstack([x, np.sin(x[:, :2]), x[:, :1] * x[:, 1:2], np.tanh(x)])

    A_hat, B_hat = fit_dynamics(lift(X), U, lift(Xn))
    assert A_hat.shape == (11, 11) and B_hat.shape == (11, 2)
    np.testing.assert_allclose(A_hat[:4, :4], A, rtol=0, atol=1e-9)
    np.testing.assert_allclose(A_hat[:4, 4:], 0.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(B_hat[:4], B, rtol=0, atol=1e-9)


def test_rbf_dictionary_on_a_linear_system_predicts_the_state_exactly():
    A, B, X, U, Xn = _linear_system(seed=2)
    model = KoopmanModel(RBFLifting(n_centers=15), ridge=0.0).fit(X, U, Xn)
    assert model.n_lifted_ == 4 + 15
    assert isinstance(model.lifting_, RBFLifting)
    # One step.
    Z = model.lift(X)
    np.testing.assert_allclose(model.step(Z, U) @ model.Cx_.T, Xn, rtol=0, atol=1e-9)
    # Many steps: the state block never picks up the RBF features.
    _, _, Xt, Ut, _ = _linear_system(seed=3, n_traj=1, steps=20)
    x = Xt[0]
    truth = [x]
    for u in Ut:
        x = A @ x + B @ u
        truth.append(x)
    np.testing.assert_allclose(model.predict_states(Xt[0], Ut), np.array(truth), rtol=0, atol=1e-8)
    np.testing.assert_allclose(model.predict(Xt[0], Ut), np.array(truth)[:-1], rtol=0, atol=1e-8)


def test_output_map_is_recovered_exactly():
    _, _, X, U, _ = _linear_system(seed=4)
    rng = np.random.default_rng(0)
    C, D = rng.normal(size=(3, 4)), rng.normal(size=(3, 2))
    C_hat, D_hat = fit_output(X, U, X @ C.T + U @ D.T)
    np.testing.assert_allclose(C_hat, C, rtol=0, atol=1e-9)
    np.testing.assert_allclose(D_hat, D, rtol=0, atol=1e-9)
    C_only, D_none = fit_output(X, None, X @ C.T)
    np.testing.assert_allclose(C_only, C, rtol=0, atol=1e-9)
    assert D_none.shape == (3, 0)


def test_ridge_matches_the_normal_equations_and_shrinks():
    rng = np.random.default_rng(1)
    Phi, T = rng.normal(size=(50, 6)), rng.normal(size=(50, 2))
    Phi[:, 2] *= 100.0  # units must not matter
    lam = 0.3
    s = np.sqrt(np.mean(Phi**2, axis=0))
    P = Phi / s
    expected = np.linalg.solve(P.T @ P / 50 + lam * np.eye(6), P.T @ T / 50) / s[:, None]
    np.testing.assert_allclose(ridge_lstsq(Phi, T, lam), expected, rtol=1e-10, atol=1e-12)
    rescaled = ridge_lstsq(Phi * 1e3, T, lam) * 1e3
    np.testing.assert_allclose(rescaled, ridge_lstsq(Phi, T, lam), rtol=1e-9, atol=1e-12)
    assert np.linalg.norm(ridge_lstsq(Phi, T, 10.0)) < np.linalg.norm(ridge_lstsq(Phi, T, 0.0))
    with pytest.raises(ParameterError, match="ridge"):
        ridge_lstsq(Phi, T, -1.0)


def test_torch_ridge_solve_agrees_with_numpy():
    import torch

    from rkmpc.learning.koopman.torch_ops import ridge_solve

    rng = np.random.default_rng(2)
    Phi, T = rng.normal(size=(80, 5)), rng.normal(size=(80, 3))
    got = ridge_solve(torch.as_tensor(Phi), torch.as_tensor(T), 1e-3).numpy()
    expected = np.linalg.solve(Phi.T @ Phi / 80 + 1e-3 * np.eye(5), Phi.T @ T / 80)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    # Columns of unit RMS: the same problem as the numpy solver's.
    Phi /= np.sqrt(np.mean(Phi**2, axis=0))
    got = ridge_solve(torch.as_tensor(Phi), torch.as_tensor(T), 1e-3).numpy()
    np.testing.assert_allclose(got, ridge_lstsq(Phi, T, 1e-3), rtol=1e-9, atol=1e-12)


def test_shape_errors():
    X = np.zeros((10, 3))
    with pytest.raises(ParameterError, match="Z_next"):
        fit_dynamics(X, np.zeros((10, 1)), np.zeros((10, 2)))
    with pytest.raises(ParameterError, match="samples"):
        fit_dynamics(X, np.zeros((9, 1)), X)
    with pytest.raises(ParameterError, match="NaN"):
        fit_dynamics(np.full((10, 3), np.nan), np.zeros((10, 1)), X)
