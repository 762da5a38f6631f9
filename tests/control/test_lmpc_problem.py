import numpy as np
import pytest

from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.linear.problem import KinematicMPCProblem
from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.kinematic import linearize_discrete
from rkmpc.vehicle.params import f1tenth


def _reference(n, seed=0):
    rng = np.random.default_rng(seed)
    theta = np.cumsum(rng.normal(0, 0.1, n)) + 2.0
    v = 2.0 + rng.uniform(0, 2, n)
    delta = rng.uniform(-0.3, 0.3, n)
    return theta, v, delta


def test_condensed_prediction_equals_rollout():
    cfg = LMPCConfig(horizon=12)
    prob = KinematicMPCProblem(cfg, f1tenth())
    theta, v, delta = _reference(12)
    Phi, Gamma = prob.prediction_matrices(theta, v, delta)
    A, B = linearize_discrete(theta, v, delta, f1tenth().wheelbase, cfg.dt)
    rng = np.random.default_rng(1)
    xi = rng.normal(size=3)
    U = rng.normal(size=(12, 2))
    states = []
    x = xi.copy()
    for k in range(12):
        x = A[k] @ x + B[k] @ U[k]
        states.append(x)
    np.testing.assert_allclose(Phi @ xi + Gamma @ U.ravel(), np.concatenate(states), atol=1e-12)


def test_qp_gradient_matches_cost():
    # f and H reproduce the cost of the condensed problem (finite differences).
    cfg = LMPCConfig(horizon=8)
    veh = f1tenth()
    prob = KinematicMPCProblem(cfg, veh)
    theta, v, delta = _reference(8, seed=3)
    Phi, Gamma = prob.prediction_matrices(theta, v, delta)
    u_ref = np.column_stack([v, delta])
    u_prev = np.array([1.5, 0.05])
    xi0 = np.array([0.1, -0.2, 0.05])
    H, f, *_ = prob.qp_numbers(xi0, u_ref, u_prev, Phi, Gamma, (0.5 * v, v))

    def cost(U):
        X = (Phi @ xi0 + Gamma @ U).reshape(-1, 3)
        w = np.array([cfg.position_weight, cfg.position_weight, cfg.heading_weight])
        c = np.sum(X**2 * w)
        Ua = U.reshape(-1, 2) + u_ref
        c += np.sum(U.reshape(-1, 2) ** 2 * [cfg.speed_weight, cfg.steer_weight])
        du = np.diff(np.vstack([u_prev, Ua]), axis=0)
        c += np.sum(du**2 * [cfg.speed_rate_weight, cfg.steer_rate_weight])
        return c

    rng = np.random.default_rng(0)
    U = rng.normal(size=16) * 0.1
    U2 = rng.normal(size=16) * 0.1
    # cost(U) - cost(U2) == quadratic model difference
    q = lambda z: 0.5 * z @ H @ z + f @ z  # noqa: E731
    assert cost(U) - cost(U2) == pytest.approx(q(U) - q(U2), rel=1e-9)


def test_config_validation():
    with pytest.raises(ParameterError, match="horizon"):
        LMPCConfig(horizon=1)
    with pytest.raises(ParameterError, match="heading_weight"):
        LMPCConfig(heading_weight=-1.0)


def test_general_condense_matches_kinematic_fast_path():
    from rkmpc.control.linear.problem import condense

    cfg = LMPCConfig(horizon=10)
    prob = KinematicMPCProblem(cfg, f1tenth())
    theta, v, delta = _reference(10, seed=5)
    Phi, Gamma = prob.prediction_matrices(theta, v, delta)
    A, B = linearize_discrete(theta, v, delta, f1tenth().wheelbase, cfg.dt)
    Phi2, Gamma2 = condense(A, B)
    np.testing.assert_allclose(Phi2, Phi, atol=1e-12)
    np.testing.assert_allclose(Gamma2, Gamma, atol=1e-12)


def test_prediction_matrices_equal_linearisation_condensed():
    # The inlined linearisation along the horizon is the one of linearize_discrete.
    from rkmpc.control.linear.problem import condense

    cfg = LMPCConfig()
    prob = KinematicMPCProblem(cfg, f1tenth())
    theta, v, delta = _reference(cfg.horizon, seed=7)
    Phi, Gamma = prob.prediction_matrices(theta, v, delta)
    Phi2, Gamma2 = condense(*linearize_discrete(theta, v, delta, f1tenth().wheelbase, cfg.dt))
    np.testing.assert_allclose(Phi, Phi2, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(Gamma, Gamma2, rtol=1e-13, atol=1e-15)


def test_qp_numbers_equal_the_textbook_formulas():
    # Precomputed (doubled, tiled) weights and bounds give the plainly assembled QP.
    cfg = LMPCConfig(horizon=10, terminal_factor=3.0, speed_margin=0.2)
    veh = f1tenth()
    prob = KinematicMPCProblem(cfg, veh)
    theta, v, delta = _reference(10, seed=2)
    Phi, Gamma = prob.prediction_matrices(theta, v, delta)
    u_ref = np.column_stack([v, delta])
    u_prev = np.array([1.5, 0.05])
    xi0 = np.array([0.1, -0.2, 0.05])
    lower, upper = 0.5 * v, np.minimum(v + cfg.speed_margin, veh.drive.max_speed)
    H, f, lb, ub, lbA, ubA = prob.qp_numbers(xi0, u_ref, u_prev, Phi, Gamma, (lower, upper))
    Q = np.diag(prob.q_diag)
    D = prob.D
    W = np.diag(prob.w_rate)
    d = (u_ref - np.vstack([u_prev, u_ref[:-1]])).ravel()
    np.testing.assert_allclose(H, 2 * (Gamma.T @ Q @ Gamma + np.diag(prob.r_diag) + D.T @ W @ D), rtol=1e-12)
    np.testing.assert_allclose(f, 2 * (Gamma.T @ Q @ Phi @ xi0 + D.T @ W @ d), rtol=1e-12, atol=1e-14)
    # The speeds between the given bounds, the steering within the car's; as deviations from u_ref.
    ub_plain = np.tile(prob.u_max, 10) - u_ref.ravel()
    ub_plain[0::2] = upper - v
    lb_plain = np.tile(prob.u_min, 10) - u_ref.ravel()
    lb_plain[0::2] = lower - v
    np.testing.assert_array_equal(ub, ub_plain)
    np.testing.assert_array_equal(lb, lb_plain)
    np.testing.assert_array_equal(lbA, -prob.steer_step_max - d[1::2])
    np.testing.assert_array_equal(ubA, prob.steer_step_max - d[1::2])
