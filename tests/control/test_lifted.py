import numpy as np

from rkmpc.control.learned.lifted import lifted_prediction


def _rollout(A, B, C, D, z0, U, first):
    z = z0.copy()
    ys = []
    for k in range(len(U) + 1):
        u = U[k] if k < len(U) else np.zeros(B.shape[1])
        y = C @ z + (D @ u if D is not None and k < len(U) else 0.0)
        ys.append(y)
        if k < len(U):
            z = A @ z + B @ U[k]
    return np.concatenate(ys[first : first + len(U)])


def test_lifted_prediction_matches_rollout():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(5, 5)) * 0.3
    B = rng.normal(size=(5, 2))
    C = rng.normal(size=(2, 5))
    D = rng.normal(size=(2, 2))
    z0 = rng.normal(size=5)
    U = rng.normal(size=(7, 2))
    for first, d in ((0, D), (1, None), (0, None)):
        Mz, Mu = lifted_prediction(A, B, C, d, 7, first=first)
        np.testing.assert_allclose(Mz @ z0 + Mu @ U.ravel(), _rollout(A, B, C, d, z0, U, first), atol=1e-10)
