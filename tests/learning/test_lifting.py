"""Lifting dictionaries: RBF shapes and determinism, numpy copy of the torch network."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.learning.koopman.lifting import MLPLifting, RBFLifting, lifting_from_params, standardisation


@pytest.fixture
def states() -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.normal(loc=[10.0, -2.0, 0.5], scale=[5.0, 0.1, 2.0], size=(400, 3))


# ---------------------------------------------------------------- RBF


@pytest.mark.parametrize("kind", ["thin_plate", "gaussian"])
@pytest.mark.parametrize("method", ["kmeans++", "random"])
def test_rbf_shapes_and_single_vector(states, kind, method):
    lift = RBFLifting(n_centers=20, seed=1, kind=kind, method=method).fit(states)
    Z = lift(states)
    assert Z.shape == (400, 20)
    assert np.all(np.isfinite(Z))
    z = lift(states[7])
    assert z.shape == (20,)
    np.testing.assert_allclose(z, Z[7], rtol=1e-12, atol=1e-12)
    assert lift.centers_.shape == (20, 3) and lift.n_lift == 20 and lift.nx_ == 3


def test_rbf_is_seeded(states):
    a = RBFLifting(16, seed=5).fit(states)
    b = RBFLifting(16, seed=5).fit(states)
    c = RBFLifting(16, seed=6).fit(states)
    np.testing.assert_array_equal(a.centers_, b.centers_)
    np.testing.assert_array_equal(a(states), b(states))
    assert not np.array_equal(a.centers_, c.centers_)


def test_rbf_centres_are_standardised_samples(states):
    lift = RBFLifting(10, seed=0, method="random").fit(states)
    mean, std = standardisation(states)
    scaled = (states - mean) / std
    for centre in lift.centers_:
        assert np.min(np.linalg.norm(scaled - centre, axis=1)) < 1e-12


def test_rbf_values_match_definition():
    centers = np.array([[0.0, 0.0], [1.0, 2.0]])
    mean, std = np.array([1.0, -1.0]), np.array([2.0, 0.5])
    x = np.array([3.0, 0.0])  # standardised: (1, 2) -> on the second centre
    s = (x - mean) / std
    thin = RBFLifting(kind="thin_plate").set_centers(centers, 2.0, mean=mean, std=std)
    r0 = np.linalg.norm(s) / 2.0
    np.testing.assert_allclose(thin(x), [r0**2 * np.log(r0), 0.0], atol=1e-12)
    gauss = RBFLifting(kind="gaussian").set_centers(centers, 2.0, mean=mean, std=std)
    np.testing.assert_allclose(gauss(x), [np.exp(-(r0**2)), 1.0], atol=1e-12)


def test_rbf_arrays_round_trip(states):
    lift = RBFLifting(12, seed=2, kind="gaussian").fit(states)
    again = RBFLifting.from_arrays(lift.to_arrays())
    assert again.kind == "gaussian" and again.width_ == lift.width_
    np.testing.assert_array_equal(again(states), lift(states))


def test_rbf_rejects_bad_input(states):
    with pytest.raises(ParameterError, match="kind"):
        RBFLifting(kind="cubic").fit(states)
    with pytest.raises(ParameterError, match="n_centers"):
        RBFLifting(401).fit(states)
    with pytest.raises(RuntimeError, match="not fitted"):
        RBFLifting(4)(states)
    lift = RBFLifting(4).fit(states)
    with pytest.raises(ParameterError, match="shape"):
        lift(np.zeros((5, 2)))


# ---------------------------------------------------------------- MLP


def _perturb(net, seed: int) -> None:
    """Give the biases non-trivial values so that the comparison exercises them."""
    import torch

    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in net.parameters():
            p.add_(0.3 * torch.randn(p.shape, generator=gen, dtype=p.dtype))


def test_numpy_copy_matches_torch(states):
    import torch

    from rkmpc.learning.koopman.torch_ops import make_torch_mlp, network_arrays

    mean, std = standardisation(states)
    scaled = (states - mean) / std
    for dtype, tol in ((torch.float32, 1e-6), (torch.float64, 1e-12)):
        net = make_torch_mlp(3, (64, 64), 16, seed=4, dtype=dtype)
        _perturb(net, 1)
        with torch.no_grad():
            expected = net(torch.as_tensor(scaled, dtype=dtype)).double().numpy()
        lift = MLPLifting().set_network(*network_arrays(net), mean, std)
        got = lift(states)
        assert got.shape == (400, 16)
        # float32 torch rounds at ~6e-8 relative per operation; float64 agrees to rounding.
        assert np.max(np.abs(got - expected)) < tol * max(1.0, np.max(np.abs(expected)))
        np.testing.assert_allclose(lift(states[11]), got[11], rtol=0, atol=1e-12)


def test_mlp_arrays_round_trip(states):
    from rkmpc.learning.koopman.torch_ops import make_torch_mlp, network_arrays

    mean, std = standardisation(states)
    lift = MLPLifting().set_network(*network_arrays(make_torch_mlp(3, (8, 5), 4, seed=0)), mean, std)
    assert lift.hidden == (8, 5) and lift.n_lift == 4
    arrays = lift.to_arrays()
    assert set(arrays) == {"mean", "std", "W0", "W1", "W2", "b0", "b1", "b2"}
    again = MLPLifting.from_arrays(arrays)
    np.testing.assert_array_equal(again(states), lift(states))


def test_make_torch_mlp_is_seeded_and_leaves_global_rng_alone():
    import torch

    from rkmpc.learning.koopman.torch_ops import make_torch_mlp

    torch.manual_seed(123)
    before = torch.rand(3)
    torch.manual_seed(123)
    a = make_torch_mlp(2, (16, 16), 4, seed=9)
    after = torch.rand(3)
    b = make_torch_mlp(2, (16, 16), 4, seed=9)
    c = make_torch_mlp(2, (16, 16), 4, seed=10)
    torch.testing.assert_close(before, after)
    for pa, pb in zip(a.parameters(), b.parameters(), strict=True):
        assert torch.equal(pa, pb)
    assert not torch.equal(next(a.parameters()), next(c.parameters()))


def test_mlp_rejects_layers_that_do_not_chain():
    w = [np.zeros((4, 2)), np.zeros((3, 5)), np.zeros((2, 3))]
    b = [np.zeros(4), np.zeros(3), np.zeros(2)]
    with pytest.raises(ParameterError, match="layer 1"):
        MLPLifting().set_network(w, b, np.zeros(2), np.ones(2))
    with pytest.raises(RuntimeError, match="not fitted"):
        MLPLifting()(np.zeros(2))


@pytest.mark.parametrize(
    "lifting",
    [MLPLifting(n_lift=0), MLPLifting(hidden=(4,)), RBFLifting(n_centers=0), RBFLifting(method="grid")],
)
def test_liftings_reject_bad_settings(lifting):
    with pytest.raises(ParameterError):
        lifting.validate()


@pytest.mark.parametrize("lifting", [MLPLifting(8, (5, 6)), RBFLifting(7, kind="gaussian", seed=3)])
def test_settings_round_trip_through_params(lifting):
    again = lifting_from_params(lifting.get_params())
    assert type(again) is type(lifting)
    assert again.get_params() == lifting.get_params()
    assert lifting_from_params(None) is None
    with pytest.raises(ParameterError, match="unknown lifting kind"):
        lifting_from_params({"kind": "poly"})
