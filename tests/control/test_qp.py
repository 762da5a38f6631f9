import numpy as np
import pytest

from rkmpc.control.qp import QP_SOLVERS, make_qp

#: The iteration budget of the tests' solvers (the MPCs' default).
ITERATIONS = 200


def _random_qp(seed: int, n: int = 12, m: int = 5):
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(n, n))
    H = M @ M.T + n * np.eye(n)
    f = rng.normal(size=n) * 10
    A = rng.normal(size=(m, n))
    lb, ub = -np.ones(n), np.ones(n)
    lbA, ubA = -0.5 * np.ones(m), 0.5 * np.ones(m)
    return H, f, lb, ub, A, lbA, ubA


def _kkt_ok(x, H, f, lb, ub, A, lbA, ubA, tol=1e-4):
    # Feasible, and no feasible descent along a projected gradient step.
    assert np.all(x >= lb - tol) and np.all(x <= ub + tol)
    Ax = A @ x
    assert np.all(Ax >= lbA - tol) and np.all(Ax <= ubA + tol)


@pytest.mark.parametrize("name", sorted(QP_SOLVERS))
def test_backends_agree_and_update(name):
    H, f, lb, ub, A, lbA, ubA = _random_qp(0)
    ref = make_qp("daqp", max_iterations=ITERATIONS)
    ref.setup(H, f, lb, ub, A, lbA, ubA)
    qp = make_qp(name, max_iterations=ITERATIONS)
    qp.setup(H, f, lb, ub, A, lbA, ubA)
    r0 = qp.solve()
    assert r0.solved
    _kkt_ok(r0.x, H, f, lb, ub, A, lbA, ubA)
    np.testing.assert_allclose(r0.x, ref.solve().x, atol=2e-3)
    # Updating numbers changes the answer the same way in both.
    H2, f2, *_ = _random_qp(1)
    qp.update(H=H2, f=f2, ub=0.5 * ub)
    ref.update(H=H2, f=f2, ub=0.5 * ub)
    r1 = qp.solve()
    assert r1.solved
    np.testing.assert_allclose(r1.x, ref.solve().x, atol=2e-3)
    assert np.all(r1.x <= 0.5 + 1e-4)
    assert not np.allclose(r0.x, r1.x)


def test_unconstrained_optimum_matches_linear_solve():
    H, f, lb, _ub, A, lbA, ubA = _random_qp(2)
    big = 1e6 * np.ones_like(lb)
    qp = make_qp("daqp", max_iterations=ITERATIONS)
    qp.setup(H, f, -big, big, A, -1e6 * np.ones(len(lbA)), 1e6 * np.ones(len(ubA)))
    np.testing.assert_allclose(qp.solve().x, np.linalg.solve(H, -f), rtol=1e-7, atol=1e-9)


def test_iteration_limit_reports_failure():
    H, f, lb, ub, A, lbA, ubA = _random_qp(3, n=30, m=20)
    f = f * 100  # many active constraints
    qp = make_qp("daqp", max_iterations=1)
    qp.setup(H, f, lb, ub, A, lbA, ubA)
    result = qp.solve()
    assert not result.solved
    assert "iteration" in result.status


def test_unknown_solver():
    with pytest.raises(ValueError, match="known"):
        make_qp("cplex", max_iterations=ITERATIONS)


@pytest.mark.parametrize("m", [5, 0])
def test_factorized_daqp_matches_daqp_as_the_hessian_changes(m):
    # Factorising H with LAPACK and handing DAQP the problem in Cholesky coordinates
    # gives DAQP's own answer, with and without general constraints, across updates.
    H, f, lb, ub, A, lbA, ubA = _random_qp(4, m=m)
    plain, fact = (
        make_qp("daqp", max_iterations=ITERATIONS),
        make_qp("daqp", max_iterations=ITERATIONS, factorize=True),
    )
    for qp in (plain, fact):
        qp.setup(H, f, lb, ub, A, lbA, ubA)
    np.testing.assert_allclose(fact.solve().x, plain.solve().x, rtol=1e-9, atol=1e-12)
    for seed in range(5, 10):
        H2, f2, *_ = _random_qp(seed, m=m)
        scale = 0.2 * (seed - 4)
        for qp in (plain, fact):
            qp.update(H=H2, f=f2, lb=-scale * np.ones(12), ub=scale * np.ones(12))
        a, b = plain.solve(), fact.solve()
        assert a.solved and b.solved
        np.testing.assert_allclose(b.x, a.x, rtol=1e-9, atol=1e-12)
    # Only the linear term (the factor is kept).
    for qp in (plain, fact):
        qp.update(f=-f)
    np.testing.assert_allclose(fact.solve().x, plain.solve().x, rtol=1e-9, atol=1e-12)


def test_factorized_daqp_reports_an_indefinite_hessian_and_recovers():
    H, f, lb, ub, A, lbA, ubA = _random_qp(11)
    qp = make_qp("daqp", max_iterations=ITERATIONS, factorize=True)
    qp.setup(H, f, lb, ub, A, lbA, ubA)
    qp.update(H=-H)
    result = qp.solve()
    assert not result.solved and result.status == "nonconvex"
    qp.update(H=H, f=f)
    ref = make_qp("daqp", max_iterations=ITERATIONS)
    ref.setup(H, f, lb, ub, A, lbA, ubA)
    np.testing.assert_allclose(qp.solve().x, ref.solve().x, rtol=1e-9, atol=1e-12)
