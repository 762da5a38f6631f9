"""The residual MPC's slip drift (``ResidualMPCConfig.slip_drift``), against a hand computation."""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.control import Observation
from rkmpc.control.learned.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC
from rkmpc.core.errors import ParameterError


def _ideal_model() -> SimpleNamespace:
    """A residual model of a car that is exactly kinematic: ``U_p = U``, on the 5 rkmpc features."""
    return SimpleNamespace(
        A_=0.5 * np.eye(5), B_=np.zeros((5, 2)), C_=np.zeros((2, 5)), D_=np.eye(2), lift=lambda x: x
    )


def _gradient(sc, slip: float, drift: bool, limit: float = math.inf) -> tuple[np.ndarray, ResidualKoopmanMPC]:
    cfg = replace(ResidualKoopmanMPC.default_config, slip_drift=drift, slip_velocity_limit=limit)
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, _ideal_model(), config=cfg)
    p = sc.reference.path.position(3.0)
    obs = Observation(
        x=float(p[0]) + 0.02,
        y=float(p[1]),
        yaw=float(sc.reference.path.heading(3.0)),
        speed=2.0,
        yaw_rate=0.5,
        slip_angle=slip,
        steer_angle=0.05,
    )
    ctrl.lmpc.step(obs)
    pred = ctrl.lmpc.last_prediction
    assert pred is not None
    _, f = ctrl._residual_qp(obs, pred, pred.plan.reshape(-1))
    return f.copy(), ctrl


def test_slip_drift_moves_the_prediction_across_the_heading_by_v_t_beta_per_step(builtin_scenario):
    sc = builtin_scenario
    beta = 0.04
    f_off, _ = _gradient(sc, beta, drift=False)
    f_on, ctrl = _gradient(sc, beta, drift=True)
    pred = ctrl.lmpc.last_prediction
    n, T = ctrl.horizon, ctrl.dt
    # By hand: step i adds v_r,i T beta along the left normal (-sin, cos) of the reference heading.
    d = np.zeros((n, 3))
    x = y = 0.0
    for i in range(n):
        theta, v = pred.reference.theta[i], pred.u_ref[i, 0]
        x += -math.sin(theta) * v * T * beta
        y += math.cos(theta) * v * T * beta
        d[i, :2] = x, y
    # U_p = U, so the deviations move with Gamma and the gradient by 2 (Q Gamma)^T d.
    expected = 2.0 * (ctrl._q[:, None] * pred.Gamma).T @ d.ravel()
    np.testing.assert_allclose(f_on - f_off, expected, rtol=1e-9, atol=1e-12)
    assert np.abs(expected).max() > 1e-3  # the term matters
    assert ctrl.diagnostics()["slip_unmeasured"] == 0.0


def test_without_a_measured_slip_angle_the_step_goes_without_drift_and_is_counted(builtin_scenario):
    sc = builtin_scenario
    f_off, _ = _gradient(sc, math.nan, drift=False)
    f_on, ctrl = _gradient(sc, math.nan, drift=True)
    np.testing.assert_array_equal(f_on, f_off)
    assert ctrl.slip_unmeasured == 1
    assert ctrl.diagnostics()["slip_unmeasured"] == 1.0
    ctrl.reset()
    assert ctrl.slip_unmeasured == 0


def test_slip_drift_must_be_a_bool_and_is_refused_by_rkmpc_paper(builtin_scenario):
    with pytest.raises(ParameterError, match="slip_drift"):
        replace(ResidualKoopmanMPC.default_config, slip_drift=1.0)
    # rkmpc-paper's settings have no slip drift: the settings that carry one (rkmpc's) are refused
    # by rkmpc-paper where they are given, never ignored.
    with pytest.raises(TypeError, match="slip_drift"):
        replace(PaperResidualKoopmanMPC.default_config, slip_drift=True)
    cfg = replace(ResidualKoopmanMPC.default_config, slip_drift=True)
    sc = builtin_scenario
    with pytest.raises(ParameterError, match="rkmpc-paper takes a ResidualMPCConfig, got RKMPCConfig"):
        PaperResidualKoopmanMPC(sc.reference, sc.vehicle, _ideal_model(), config=cfg)


def test_the_slip_drift_is_whole_below_half_its_sideways_speed_limit_and_gone_at_it(builtin_scenario):
    sc = builtin_scenario  # _gradient's car runs at 2 m/s: it slides sideways at 2 tan(beta)
    assert ResidualKoopmanMPC.default_config.slip_velocity_limit == math.inf  # off unless a car file sets it
    f_off_small, _ = _gradient(sc, 0.04, drift=False)
    f_on_small, _ = _gradient(sc, 0.04, drift=True)
    whole, ctrl = _gradient(sc, 0.04, True, 0.2)
    np.testing.assert_array_equal(whole, f_on_small)  # 0.080 m/s, under 0.1: whole, not counted
    assert ctrl.diagnostics()["slip_drift_faded"] == 0.0
    f_off, _ = _gradient(sc, 0.075, drift=False)
    f_on, _ = _gradient(sc, 0.075, drift=True)
    part, ctrl = _gradient(sc, 0.075, True, 0.2)  # 0.150 m/s of 0.2: about half the drift, counted
    assert ctrl.slip_drift_faded == 1 and ctrl.diagnostics()["slip_drift_faded"] == 1.0
    ctrl.reset()
    assert ctrl.slip_drift_faded == 0
    weight = 2.0 - 2.0 * (2.0 * math.tan(0.075)) / 0.2
    assert 0.45 < weight < 0.55
    np.testing.assert_allclose(part - f_off, weight * (f_on - f_off), rtol=1e-9, atol=1e-12)
    f_off_big, _ = _gradient(sc, 0.12, drift=False)  # 0.241 m/s, past 0.2: no drift
    np.testing.assert_allclose(_gradient(sc, 0.12, True, 0.2)[0], f_off_big, rtol=1e-12, atol=1e-12)
    # A slow car keeps a slip angle the fast one loses: the limit is on the sideways speed.
    assert ctrl.config.slip_drift_weight(0.12, 0.5) == 1.0 and ctrl.config.slip_drift_weight(0.12, 2.0) == 0.0
    assert np.abs(f_on_small - f_off_small).max() > 1e-3


@pytest.mark.parametrize("limit", [0.0, -0.1, math.nan, "0.1", True])
def test_a_bad_slip_velocity_limit_is_refused_by_name(limit):
    with pytest.raises(ParameterError, match="slip_velocity_limit"):
        replace(ResidualKoopmanMPC.default_config, slip_velocity_limit=limit)
