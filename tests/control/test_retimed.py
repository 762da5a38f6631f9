"""The residual QP on a retimed reference (``RKMPCConfig.retimed``, :mod:`rkmpc.control.learned.progress`)."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.control import Observation
from rkmpc.control.learned.progress import ProgressSplit, linearisation
from rkmpc.control.learned.rkmpc import ResidualKoopmanMPC
from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.kinematic import kinematic_step


def _model(speed_gain: float) -> SimpleNamespace:
    """A residual model of a kinematic car whose speed loop reaches ``speed_gain`` of the command:
    ``U_p = diag(speed_gain, 1) U`` on the 5 rkmpc features."""
    return SimpleNamespace(
        A_=0.5 * np.eye(5),
        B_=np.zeros((5, 2)),
        C_=np.zeros((2, 5)),
        D_=np.diag([speed_gain, 1.0]),
        lift=lambda x: x,
    )


def _in_the_tightest_corner(sc, speed_gain: float, retimed: bool):
    """The controller, its LMPC's prediction and the observation of a car exactly on the reference
    (pose, speed and wheel angle) at the built-in track's tightest corner."""
    cfg = replace(ResidualKoopmanMPC.default_config, retimed=retimed)
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, _model(speed_gain), config=cfg)
    path = sc.reference.path
    s_grid = np.linspace(0.0, path.length, 2000, endpoint=False)
    s = float(s_grid[np.argmax(np.abs(path.curvature(s_grid)))] - 1.0)
    ref = sc.reference.horizon(s, 1, ctrl.dt)
    obs = Observation(
        x=float(ref.x[0]),
        y=float(ref.y[0]),
        yaw=float(ref.theta[0]),
        speed=float(ref.v[0]),
        yaw_rate=float(ref.v[0] * np.tan(ref.delta[0]) / sc.vehicle.wheelbase),
        slip_angle=0.0,
        steer_angle=float(ref.delta[0]),
    )
    ctrl.lmpc.step(obs)
    pred = ctrl.lmpc.last_prediction
    assert pred is not None
    return ctrl, pred, obs


def _lateral(pred, e0: np.ndarray, theta: np.ndarray) -> np.ndarray:
    return -np.sin(theta) * e0[0::3] + np.cos(theta) * e0[1::3]


def test_a_speed_deficit_is_a_lag_not_a_lateral_deviation(builtin_scenario):
    """A car 30 % slower than it is told, on the line in the tightest corner, driven by the LMPC's
    plan: the retimed prediction of its distance from the path matches the exact kinematic car's;
    the time-indexed one is off by far more, and the lag rows are exactly the distance not covered."""
    sc = builtin_scenario
    ctrl, pred, obs = _in_the_tightest_corner(sc, 0.7, retimed=False)
    plan = pred.plan.reshape(-1)
    effective = ctrl._Mu @ plan  # the features' part is zero (C = 0)
    n, T, L = ctrl.horizon, ctrl.dt, sc.vehicle.wheelbase

    # The truth: the exact kinematic car at 70 % of the planned speeds, its signed distance from the path.
    state = np.array([obs.x, obs.y, obs.yaw])
    truth = np.empty(n)
    s_hint = float(pred.reference.s[0])
    for k in range(n):
        state = kinematic_step(state, effective[2 * k : 2 * k + 2], L, T)
        p = sc.reference.project(state[0], state[1], s_hint)
        truth[k], s_hint = p.lateral, p.s

    Phi, Gamma, theta, u_ref = linearisation(pred, effective, None)
    time_indexed = _lateral(pred, Phi @ pred.xi0 + Gamma @ (effective - u_ref), theta)
    split = ProgressSplit(sc.reference, ctrl.lmpc.problem)
    Phi, Gamma, theta, u_ref = split.linearise(pred, effective)
    e0 = Phi @ pred.xi0 + Gamma @ (effective - u_ref)
    retimed = _lateral(pred, e0, theta)

    # Measured: the time-indexed prediction is 9.9 cm off the truth at the horizon's end (it
    # doubles the car's drift to the inside), the retimed one 2.2 cm (its linearisation's error).
    time_error = np.abs(time_indexed - truth).max()
    assert time_error > 0.05
    assert np.abs(retimed - truth).max() < 0.3 * time_error
    E, M = split.rows(pred, effective, ctrl._Mu, e0, Gamma @ ctrl._Mu, theta)
    lag = T * np.cumsum(0.7 * pred.plan[:, 0] - pred.u_ref[:, 0])
    np.testing.assert_allclose(E[0::3], lag, rtol=1e-12, atol=1e-12)
    assert lag[-1] < -0.1  # late by more than 10 cm at the horizon's end
    np.testing.assert_allclose(E[1::3], retimed, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(E[2::3], e0[2::3])
    # A speed correction moves the car along the track only: no lateral or heading row sees it.
    np.testing.assert_array_equal(M[1::3, 0::2], 0.0)
    np.testing.assert_array_equal(M[2::3, 0::2], 0.0)
    np.testing.assert_allclose(M[0::3, 0::2], T * 0.7 * np.tril(np.ones((n, n))), rtol=1e-12)
    assert split.horizon == n


def test_retimed_points_lie_at_the_distance_the_car_covers(builtin_scenario):
    sc = builtin_scenario
    ctrl, pred, _ = _in_the_tightest_corner(sc, 0.7, retimed=True)
    effective = ctrl._Mu @ pred.plan.reshape(-1)
    split = ProgressSplit(sc.reference, ctrl.lmpc.problem)
    _, _, theta, u_ref = split.linearise(pred, effective)
    distance = np.cumsum(np.maximum(effective[0::2], 0.0) * ctrl.dt)
    ref = sc.reference.along(float(pred.reference.s[0]), distance)
    np.testing.assert_allclose(theta, ref.theta[1:])
    np.testing.assert_allclose(u_ref[0::2], effective[0::2])
    np.testing.assert_allclose(u_ref[1::2], ref.delta[:-1])


def _inward_correction(sc, speed_gain: float, retimed: bool) -> float:
    """The residual QP's unconstrained steering correction (rad) toward the inside of the corner."""
    ctrl, pred, obs = _in_the_tightest_corner(sc, speed_gain, retimed=retimed)
    H, f = ctrl._residual_qp(obs, pred, pred.plan.reshape(-1))
    correction = np.linalg.solve(H, -f)
    return float(np.sign(pred.reference.delta[0]) * correction[1])


def test_the_residual_does_not_cut_the_corner_of_a_slow_car(builtin_scenario):
    """On the line in the tightest corner, a car whose speed loop reaches 70 % of the command: the
    time-indexed residual QP steers it 0.13 rad toward the inside; retimed, it steers it a little
    outward (the LMPC's steering schedule, driven late, takes the slow car 7 cm inside: the first
    test). A car on schedule needs no correction either way."""
    sc = builtin_scenario
    assert _inward_correction(sc, 0.7, retimed=False) > 0.1
    assert -0.03 < _inward_correction(sc, 0.7, retimed=True) < 0.0
    for retimed in (False, True):
        assert abs(_inward_correction(sc, 1.0, retimed=retimed)) < 1e-3


def test_on_the_time_indexed_linearisation_the_residual_qp_is_unchanged(builtin_scenario):
    sc = builtin_scenario
    ctrl, pred, obs = _in_the_tightest_corner(sc, 1.0, retimed=False)
    plan = pred.plan.reshape(-1)
    H, f = ctrl._residual_qp(obs, pred, plan)
    # By hand: the LMPC's own prediction with U_p = U.
    e0 = pred.Phi @ pred.xi0 + pred.Gamma @ (plan - pred.u_ref.ravel())
    GM = pred.Gamma @ ctrl._Mu
    GtQ = (ctrl._q[:, None] * GM).T
    np.testing.assert_allclose(f, 2.0 * GtQ @ e0, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(H, 2.0 * (GtQ @ GM + ctrl._R), rtol=1e-12)


def test_retimed_must_be_a_bool():
    with pytest.raises(ParameterError, match="retimed"):
        replace(ResidualKoopmanMPC.default_config, retimed=1)
