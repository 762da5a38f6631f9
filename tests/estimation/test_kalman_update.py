"""The square-root Kalman update: the Cholesky factors on floats, and the update against the textbook form."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.estimation.kalman import apply, apply_one, cholesky2, cholesky3


def test_the_factors_are_numpys_cholesky_and_none_when_not_positive():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((3, 3))
    S = A @ A.T + 0.1 * np.eye(3)
    c00, c10, c20, c11, c21, c22 = cholesky3(S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2])
    np.testing.assert_allclose(
        [[c00, 0, 0], [c10, c11, 0], [c20, c21, c22]], np.linalg.cholesky(S), rtol=1e-12
    )
    np.testing.assert_allclose(
        np.array(cholesky2(S[0, 0], S[0, 1], S[1, 1]))[[0, 1, 2]],
        np.linalg.cholesky(S[:2, :2])[[0, 1, 1], [0, 0, 1]],
        rtol=1e-12,
    )
    assert cholesky3(1.0, 2.0, 0.0, 1.0, 0.0, 1.0) is None
    assert cholesky2(-1.0, 0.0, 1.0) is None and cholesky2(1.0, 1.0, 1.0) is None


def test_the_update_is_the_textbook_kalman_update():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((8, 8))
    P = A @ A.T + np.eye(8)
    x = rng.standard_normal(8)
    H = rng.standard_normal((3, 8))
    R = np.diag([0.1, 0.2, 0.3])
    nu = rng.standard_normal(3)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    C = np.linalg.cholesky(S)
    D = np.linalg.inv(C)
    x_new, P_new = apply(x, P, P @ H.T, D.T, tuple(D @ nu))
    np.testing.assert_allclose(x_new, x + K @ nu, rtol=1e-10)
    np.testing.assert_allclose(P_new, P - K @ S @ K.T, rtol=1e-9, atol=1e-12)
    assert np.array_equal(P_new, P_new.T)  # exactly symmetric
    h = H[0]
    s = float(h @ P @ h) + 0.1
    x_one, P_one = apply_one(x, P, P @ h, s, 0.5)
    np.testing.assert_allclose(x_one, x + P @ h * 0.5 / s, rtol=1e-12)
    np.testing.assert_allclose(P_one, P - np.outer(P @ h, P @ h) / s, rtol=1e-10, atol=1e-12)
    assert np.array_equal(P_one, P_one.T)
    with pytest.raises(ValueError):
        apply_one(x, P, P @ h, -1.0, 0.5)  # math.sqrt of a negative variance
