"""Small PyTorch building blocks of the training of a lifting network.

Seeding and runtime settings of torch, the pseudo-Huber function, the differentiable ridge least
squares, the rollout of a lifted linear model, and the lifting network itself (made fresh, and read
back as numpy arrays). :mod:`rkmpc.learning.koopman.training` puts them together.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch

from rkmpc.core.errors import ParameterError
from rkmpc.learning.koopman.settings import TRAINING_THREADS

__all__ = [
    "make_torch_mlp",
    "network_arrays",
    "pseudo_huber",
    "ridge_solve",
    "rollout",
    "set_torch_seed",
    "torch_runtime",
]


def set_torch_seed(seed: int) -> None:
    """Seed torch's global (CPU) random generator."""
    torch.manual_seed(int(seed))


@contextmanager
def torch_runtime(threads: int | None = None, deterministic: bool = True) -> Iterator[None]:
    """Temporarily set torch's thread count and deterministic-algorithms flag; restores both on exit.

    Parameters
    ----------
    threads : int, optional
        Intra-op threads; default :data:`~rkmpc.learning.koopman.settings.TRAINING_THREADS`
        (1) on every machine, so that a model does not depend on the machine's cores or load.
    deterministic : bool
        Whether to call ``torch.use_deterministic_algorithms(True)`` for the duration.
    """
    old_threads = torch.get_num_threads()
    old_det = torch.are_deterministic_algorithms_enabled()
    old_warn = torch.is_deterministic_algorithms_warn_only_enabled()
    torch.set_num_threads(threads if threads is not None else TRAINING_THREADS)
    if deterministic:
        torch.use_deterministic_algorithms(True, warn_only=True)
    try:
        yield
    finally:
        torch.set_num_threads(old_threads)
        torch.use_deterministic_algorithms(old_det, warn_only=old_warn)


def pseudo_huber(x: torch.Tensor, delta: float) -> torch.Tensor:
    """Pseudo-Huber function ``delta^2 (sqrt(1 + (x / delta)^2) - 1)``, elementwise.

    Quadratic (``x^2 / 2``) for ``|x| << delta`` and linear (``delta |x|``) for ``|x| >> delta``.
    """
    return delta**2 * (torch.sqrt(1.0 + (x / delta) ** 2) - 1.0)


def ridge_solve(Phi: torch.Tensor, T: torch.Tensor, ridge: float) -> torch.Tensor:
    """Differentiable ridge least squares ``argmin_W ||Phi W - T||^2 / n + ridge ||W||^2``.

    Solved through the normal equations ``(Phi^T Phi / n + ridge I) W = Phi^T T / n`` in float64 (the
    Gram matrix of learned features is easily ill-conditioned in float32); the result is cast back to
    the dtype of ``Phi``.

    Parameters
    ----------
    Phi : Tensor, shape (n, p)
    T : Tensor, shape (n, q)
    ridge : float
        Positive weight.

    Returns
    -------
    Tensor, shape (p, q)
    """
    n = Phi.shape[0]
    P = Phi.to(torch.float64)
    gram = P.T @ P / n + ridge * torch.eye(P.shape[1], dtype=torch.float64)
    rhs = P.T @ T.to(torch.float64) / n
    return torch.linalg.solve(gram, rhs).to(Phi.dtype)


def rollout(z0: torch.Tensor, U: torch.Tensor, A: torch.Tensor, B: torch.Tensor) -> torch.Tensor:
    """Roll the lifted linear model forward.

    Parameters
    ----------
    z0 : Tensor, shape (M, nz)
        Initial lifted states.
    U : Tensor, shape (M, H, nu)
        Inputs.
    A : Tensor, shape (nz, nz)
    B : Tensor, shape (nz, nu)

    Returns
    -------
    Tensor, shape (M, H, nz)
        Predicted lifted states ``z_1 .. z_H``.
    """
    steps = []
    z = z0
    for k in range(U.shape[1]):
        z = z @ A.T + U[:, k] @ B.T
        steps.append(z)
    return torch.stack(steps, dim=1)


def make_torch_mlp(
    nx: int,
    hidden: tuple[int, int] = (64, 64),
    n_lift: int = 16,
    seed: int = 0,
    dtype: torch.dtype | None = None,
) -> torch.nn.Sequential:
    """A fresh lifting network ``Linear-ReLU-Linear-ReLU-Linear`` for standardised inputs.

    Parameters
    ----------
    nx : int
        Input size (state features).
    hidden : tuple of two int
        Hidden layer widths.
    n_lift : int
        Output size (number of learned features).
    seed : int
        Seed of the weight initialisation; the global torch random state is left untouched.
    dtype : torch.dtype, optional
        Parameter dtype (default: torch's default, float32).
    """
    if len(hidden) != 2 or min(hidden) < 1 or nx < 1 or n_lift < 1:
        raise ParameterError(f"bad network sizes: nx={nx}, hidden={hidden}, n_lift={n_lift}")
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        net = torch.nn.Sequential(
            torch.nn.Linear(nx, int(hidden[0])),
            torch.nn.ReLU(),
            torch.nn.Linear(int(hidden[0]), int(hidden[1])),
            torch.nn.ReLU(),
            torch.nn.Linear(int(hidden[1]), n_lift),
        )
    if dtype is not None:
        net = net.to(dtype=dtype)
    return net


def network_arrays(module: torch.nn.Module) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Weights and biases (float64 numpy copies) of a network made by :func:`make_torch_mlp`.

    Raises
    ------
    ParameterError
        When the network does not have exactly three ``Linear`` layers.
    """
    layers = [m for m in module.modules() if isinstance(m, torch.nn.Linear)]
    if len(layers) != 3:
        raise ParameterError(f"expected a network of three Linear layers, found {len(layers)}")
    weights = [layer.weight.detach().to(torch.float64).cpu().numpy().copy() for layer in layers]
    biases = []
    for layer in layers:
        if layer.bias is None:
            biases.append(np.zeros(layer.out_features))
        else:
            biases.append(layer.bias.detach().to(torch.float64).cpu().numpy().copy())
    return weights, biases
