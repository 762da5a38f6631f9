"""Torch helpers for learning the lifting network of :class:`rkmpc.learning.koopman.KoopmanModel`.

The loss follows the paper (Sec. IV-B, Eq. "net loss function"): for a batch, lift states and successors,
compute ``A, B`` in closed form by least squares on the *current* lifting (differentiably), and apply the
pseudo-Huber function ``delta^2 (sqrt(1 + (L_a / delta)^2) - 1)`` to the mean absolute one-step residual
``L_a`` in the lifted space. Two terms are added to keep the features useful (and from shrinking
towards zero, which would make ``L_a`` vanish without helping the prediction of the state):

* the reconstruction error of the output (or of the state, when it is not part of the lifted vector)
  through a least-squares output matrix ``C``;
* ``rollout_weight`` times the multi-step prediction error of the state over ``rollout_steps`` steps on
  windows of consecutive samples.

All quantities in the loss are in scaled units: states divided by their standard deviation, inputs by
theirs. The importing of this module pulls in torch; the rest of the package does not need it at
inference time.
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch

from rkmpc.learning.lifting import make_torch_mlp

__all__ = [
    "TrainingResult",
    "consecutive_windows",
    "pseudo_huber",
    "ridge_solve",
    "rollout",
    "set_torch_seed",
    "torch_runtime",
    "train_lifting",
]

#: Smallest ridge used inside training, where the Gram matrix of ReLU features can be singular.
MIN_TRAINING_RIDGE = 1e-8

#: A batch whose loss exceeds this multiple of the best epoch loss so far is skipped (no step).
SKIP_LOSS_FACTOR = 1e3

#: Gradient norm clip of every optimiser step.
MAX_GRAD_NORM = 10.0


def set_torch_seed(seed: int) -> None:
    """Seed torch's global (CPU) random generator."""
    torch.manual_seed(int(seed))


@contextmanager
def torch_runtime(threads: int | None = None, deterministic: bool = True) -> Iterator[None]:
    """Temporarily set torch's thread count and deterministic-algorithms flag; restores both on exit.

    Parameters
    ----------
    threads : int, optional
        Intra-op threads; default ``min(2, os.cpu_count(), torch.get_num_threads())``, so a
        process that limited torch to one thread (a parallel worker) keeps one: two
        processes each spinning two threads on two cores slow small-batch training down
        about tenfold.
    deterministic : bool
        Whether to call ``torch.use_deterministic_algorithms(True)`` for the duration.
    """
    old_threads = torch.get_num_threads()
    old_det = torch.are_deterministic_algorithms_enabled()
    old_warn = torch.is_deterministic_algorithms_warn_only_enabled()
    default = max(1, min(2, os.cpu_count() or 1, old_threads))
    torch.set_num_threads(threads if threads is not None else default)
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


def consecutive_windows(
    X: np.ndarray, U: np.ndarray, X_next: np.ndarray, steps: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """Windows of ``steps`` consecutive transitions found in one-step data.

    Transition ``k`` is followed by ``k + 1`` when ``X_next[k] == X[k + 1]`` exactly (as for samples
    taken in order from trajectories).

    Parameters
    ----------
    X, X_next : ndarray, shape (N, nx)
    U : ndarray, shape (N, nu)
    steps : int
        Window length in transitions (H).

    Returns
    -------
    (Xw, Uw) with shapes (M, H+1, nx) and (M, H, nu), or None when there is no such window.
    """
    n = X.shape[0]
    if steps < 1 or n < steps:
        return None
    linked = np.all(X_next[:-1] == X[1:], axis=1)  # (N-1,)
    # A window starting at i needs links i .. i+steps-2 (steps-1 of them).
    ok = np.ones(n - steps + 1, dtype=bool)
    if steps > 1:
        count = np.concatenate([[0], np.cumsum(linked)])
        starts = np.arange(n - steps + 1)
        ok = (count[starts + steps - 1] - count[starts]) == steps - 1
    starts = np.flatnonzero(ok)
    if starts.size == 0:
        return None
    offsets = np.arange(steps)
    Xw = np.concatenate([X[starts[:, None] + offsets], X_next[starts + steps - 1][:, None, :]], axis=1)
    Uw = U[starts[:, None] + offsets]
    return Xw, Uw


@dataclass
class TrainingResult:
    """What :func:`train_lifting` hands back."""

    net: torch.nn.Sequential
    history: list[tuple[int, float]]
    stopped_early: bool
    epochs_run: int


def train_lifting(
    X: np.ndarray,
    U: np.ndarray,
    X_next: np.ndarray,
    *,
    mean: np.ndarray,
    std: np.ndarray,
    u_scale: np.ndarray,
    Y: np.ndarray | None,
    y_scale: np.ndarray | None,
    windows: tuple[np.ndarray, np.ndarray] | None,
    include_state: bool,
    hidden: tuple[int, int],
    n_lift: int,
    epochs: int,
    learning_rate: float,
    batch_size: int,
    huber_delta: float,
    rollout_steps: int,
    rollout_weight: float,
    ridge: float,
    seed: int,
    deadline: float | None,
    on_epoch: Callable[[int, float], None] | None = None,
    dtype: torch.dtype = torch.float64,
) -> TrainingResult:
    """Train the lifting network with Adam (see the module docstring for the loss).

    Parameters
    ----------
    X, X_next : ndarray, shape (N, nx)
        States and successors, original units.
    U : ndarray, shape (N, nu)
        Inputs.
    mean, std : ndarray, shape (nx,)
        State standardisation (the network sees ``(x - mean) / std``; the lifted vector holds ``x / std``).
    u_scale : ndarray, shape (nu,)
        Input scaling (inputs are divided by it).
    Y : ndarray, shape (N, ny), optional
        Output targets; ``y_scale`` (ny,) divides them.
    windows : tuple (Xw (M, H+1, nx), Uw (M, H, nu)), optional
        Consecutive sequences for the rollout term; ``H >= rollout_steps`` is not required (the shorter
        one is used), longer windows are sampled at a random offset each step.
    deadline : float, optional
        ``time.perf_counter()`` value after which training stops (after the current step).
    on_epoch : callable, optional
        Called as ``on_epoch(epoch, mean_loss)`` after epoch 0 (the untrained network) and each epoch.
    dtype : torch.dtype
        Precision of the network and the loss. float64 by default: at these sizes it costs about the
        same as float32 on a CPU, keeps the per-batch least squares well conditioned, and makes the
        exported numpy lifting reproduce the trained network to rounding.

    Returns
    -------
    TrainingResult
    """
    rng = np.random.default_rng(seed)
    nx = X.shape[1]
    ridge = max(float(ridge), MIN_TRAINING_RIDGE)

    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype)

    Xs = tensor((X - mean) / std)
    Xns = tensor((X_next - mean) / std)
    Xsc = tensor(X / std)
    Xnsc = tensor(X_next / std)
    Us = tensor(U / u_scale)
    Ys = None if Y is None or y_scale is None else tensor(Y / y_scale)

    Xw_s = Xw_sc = Uw_s = None
    horizon = 0
    if windows is not None and rollout_weight > 0 and rollout_steps > 0:
        Xw, Uw = windows
        horizon = min(rollout_steps, Uw.shape[1])
        Xw_s = tensor((Xw - mean) / std)
        Xw_sc = tensor(Xw / std)
        Uw_s = tensor(Uw / u_scale)
    n_windows = 0 if Xw_s is None else Xw_s.shape[0]
    window_batch = min(n_windows, max(64, batch_size // 4))

    with torch.random.fork_rng(devices=[]):
        set_torch_seed(seed)
        net = make_torch_mlp(nx, hidden, n_lift, seed, dtype=dtype)
        optimiser = torch.optim.Adam(net.parameters(), lr=learning_rate)
        n = X.shape[0]
        batch = min(batch_size, n)

        def lifted(xs: torch.Tensor, xsc: torch.Tensor) -> torch.Tensor:
            psi = net(xs)
            return torch.cat([xsc, psi], dim=-1) if include_state else psi

        def batch_loss(idx: np.ndarray) -> torch.Tensor:
            t = torch.as_tensor(idx)
            z = lifted(Xs[t], Xsc[t])
            zn = lifted(Xns[t], Xnsc[t])
            u = Us[t]
            phi = torch.cat([z, u], dim=1)
            W = ridge_solve(phi, zn, ridge)
            nz = z.shape[1]
            A, B = W[:nz].T, W[nz:].T
            loss = pseudo_huber(torch.mean(torch.abs(zn - phi @ W)), huber_delta)
            state_map = None
            if not include_state:
                state_map = ridge_solve(z, Xsc[t], ridge).T  # (nx, nz)
                recon = torch.mean(torch.abs(Xsc[t] - z @ state_map.T))
                loss = loss + pseudo_huber(recon, huber_delta)
            if Ys is not None:
                Wy = ridge_solve(phi, Ys[t], ridge)
                loss = loss + pseudo_huber(torch.mean(torch.abs(Ys[t] - phi @ Wy)), huber_delta)
            if Xw_s is not None and Xw_sc is not None and Uw_s is not None and horizon > 0:
                w = torch.as_tensor(rng.choice(n_windows, size=window_batch, replace=False))
                off = int(rng.integers(0, Uw_s.shape[1] - horizon + 1))
                z0 = lifted(Xw_s[w, off], Xw_sc[w, off])
                zs = rollout(z0, Uw_s[w, off : off + horizon], A, B)
                xs_pred = zs[..., :nx] if state_map is None else zs @ state_map.T
                err = torch.mean(torch.abs(xs_pred - Xw_sc[w, off + 1 : off + 1 + horizon]))
                loss = loss + rollout_weight * pseudo_huber(err, huber_delta)
            return loss

        n_batches = max(1, int(np.ceil(n / batch)))  # near-equal batches: no tiny remainder batch

        history: list[tuple[int, float]] = []
        with torch.no_grad():
            initial = [float(batch_loss(idx)) for idx in np.array_split(rng.permutation(n), n_batches)]
        history.append((0, float(np.mean(initial))))
        if on_epoch is not None:
            on_epoch(0, history[-1][1])

        stopped = False
        epochs_run = 0
        # Divergence guards: a batch whose least-squares fit is ill-conditioned can give a huge
        # loss and gradient; such a batch is skipped, gradients are clipped, and the network of
        # the epoch with the lowest mean loss is the one returned.
        best_loss = history[-1][1] if math.isfinite(history[-1][1]) else math.inf
        best_state = copy.deepcopy(net.state_dict())
        for epoch in range(1, epochs + 1):
            losses = []
            for idx in np.array_split(rng.permutation(n), n_batches):
                optimiser.zero_grad(set_to_none=True)
                loss = batch_loss(idx)
                value = float(loss.detach())
                if not math.isfinite(value) or value > SKIP_LOSS_FACTOR * max(best_loss, 1e-12):
                    losses.append(math.nan)
                else:
                    loss.backward()
                    torch.nn.utils.clip_grad_norm_(net.parameters(), MAX_GRAD_NORM)
                    optimiser.step()
                    losses.append(value)
                if deadline is not None and time.perf_counter() > deadline:
                    stopped = True
                    break
            if losses:
                kept = [v for v in losses if math.isfinite(v)]
                mean_loss = float(np.mean(kept)) if kept else math.nan
                history.append((epoch, mean_loss))
                epochs_run = epoch
                if math.isfinite(mean_loss) and mean_loss < best_loss:
                    best_loss = mean_loss
                    best_state = copy.deepcopy(net.state_dict())
                if on_epoch is not None:
                    on_epoch(epoch, history[-1][1])
            if stopped:
                break
        net.load_state_dict(best_state)
    net.eval()
    return TrainingResult(net=net, history=history, stopped_early=stopped, epochs_run=epochs_run)
