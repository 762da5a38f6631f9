"""Tests of the simplified Pacejka lateral force."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.tyres import pacejka_lateral_force, pacejka_lateral_force_array


def test_scalar_and_array_agree_and_are_odd() -> None:
    tyre = f1tenth().tyre_rear
    alphas = np.linspace(-0.6, 0.6, 25)
    forces = pacejka_lateral_force_array(alphas, 20.0, tyre, 0.8)
    for alpha, force in zip(alphas, forces, strict=True):
        assert pacejka_lateral_force(float(alpha), 20.0, tyre, 0.8) == pytest.approx(force, rel=1e-14)
    np.testing.assert_allclose(forces, -forces[::-1], atol=1e-12)


def test_small_slip_slope_is_cornering_stiffness() -> None:
    tyre = f1tenth().tyre_front
    eps = 1e-7
    slope = pacejka_lateral_force(eps, 15.0, tyre, 0.9) / eps
    assert slope == pytest.approx(0.9 * 15.0 * tyre.cornering_stiffness_per_load, rel=1e-9)


def test_force_never_exceeds_peak() -> None:
    tyre = f1tenth().tyre_front
    forces = pacejka_lateral_force_array(np.linspace(0, math.pi / 2, 200), 10.0, tyre, 1.0)
    assert np.max(np.abs(forces)) <= 10.0 * tyre.D + 1e-12
