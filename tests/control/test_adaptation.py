"""Recursive least squares on the residual model's output map: recovery, forgetting, bounds."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control.learned.adaptation import AdaptationConfig, OutputRLS
from rkmpc.core.errors import ParameterError


def _data(theta: np.ndarray, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(n, 3))
    u = rng.normal(size=(n, 2))
    y = np.hstack([z, u]) @ theta.T
    return z, u, y


def test_rls_moves_the_map_toward_the_car_within_its_bounds() -> None:
    trained = np.array([[1.0, 0.0, 0.5, 1.0, 0.0], [0.0, 2.0, 0.0, 0.0, 1.0]])
    true = trained.copy()
    true[0, 3] = 1.3  # the car needs 30 % more of the first input: within the 50 % bound
    rls = OutputRLS(trained[:, :3], trained[:, 3:], AdaptationConfig(enabled=True, initial_covariance=1.0))
    for z, u, y in zip(*_data(true, 400), strict=True):
        rls.update(z, u, y)
    np.testing.assert_allclose(np.hstack([rls.C, rls.D]), true, atol=1e-3)
    assert rls.updates == 400 and rls.skipped == 0


def test_rls_never_leaves_its_bounds() -> None:
    trained = np.array([[1.0, 0.0, 0.0, 1.0, 0.0]])
    true = trained.copy()
    true[0, 3] = 3.0  # far beyond: stops at 1 + 0.5 * 1
    rls = OutputRLS(trained[:, :3], trained[:, 3:], AdaptationConfig(enabled=True, initial_covariance=1.0))
    for z, u, y in zip(*_data(true, 300), strict=True):
        rls.update(z, u, y)
    assert rls.D[0, 0] == pytest.approx(1.5)
    assert np.all(np.abs(np.hstack([rls.C, rls.D]) - trained) <= 0.5 + 1e-12)


def test_outliers_and_non_finite_steps_are_skipped_and_reset_restores_the_map() -> None:
    trained = np.array([[1.0, 0.0, 0.0, 1.0, 0.0]])
    rls = OutputRLS(trained[:, :3], trained[:, 3:], AdaptationConfig(enabled=True, outlier=5.0))
    z, u, y = _data(trained, 50)
    for k in range(50):
        rls.update(z[k], u[k], y[k] + 0.01)
    assert not rls.update(z[0], u[0], y[0] + 100.0)
    assert not rls.update(z[0] * np.nan, u[0], y[0])
    assert rls.skipped == 2
    rls.reset()
    np.testing.assert_array_equal(np.hstack([rls.C, rls.D]), trained)
    assert rls.updates == 0


def test_settings_are_validated() -> None:
    with pytest.raises(ParameterError, match="forgetting"):
        AdaptationConfig(forgetting=1.2)
    with pytest.raises(ParameterError):
        AdaptationConfig(max_change=0.0)
