"""Torch training of the lifting network of :class:`rkmpc.learning.koopman.lifting.MLPLifting`.

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
theirs. A run is seeded (:attr:`MLPTraining.seed`): the same data and settings give the same network,
history and loss to the last bit. Importing this module pulls in torch; the rest of the package does not
need it at inference time.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from rkmpc.learning.koopman.settings import MLPTraining
from rkmpc.learning.koopman.torch_ops import (
    make_torch_mlp,
    network_arrays,
    pseudo_huber,
    ridge_solve,
    rollout,
    set_torch_seed,
)

__all__ = [
    "Scaling",
    "TrainingArrays",
    "TrainingResult",
    "train_network",
]

#: Smallest ridge used inside training, where the Gram matrix of ReLU features can be singular.
MIN_TRAINING_RIDGE = 1e-8

#: A batch whose loss exceeds this multiple of the best epoch loss so far is skipped (no step).
SKIP_LOSS_FACTOR = 1e3

#: Gradient norm clip of every optimiser step.
MAX_GRAD_NORM = 10.0


@dataclass(frozen=True)
class TrainingArrays:
    """The data of one training run, original units.

    Parameters
    ----------
    X, X_next : ndarray, shape (N, nx)
        States and successors.
    U : ndarray, shape (N, nu)
        Inputs.
    Y : ndarray, shape (N, ny), optional
        Output targets.
    windows : tuple (Xw (M, H+1, nx), Uw (M, H, nu)), optional
        Consecutive sequences for the rollout term; ``H >= rollout_steps`` is not required (the
        shorter one is used), longer windows are sampled at a random offset each step.
    """

    X: np.ndarray
    U: np.ndarray
    X_next: np.ndarray
    Y: np.ndarray | None = None
    windows: tuple[np.ndarray, np.ndarray] | None = None


@dataclass(frozen=True)
class Scaling:
    """Scales of the loss: the network sees ``(x - mean) / std``; the lifted vector holds ``x / std``.

    Parameters
    ----------
    mean, std : ndarray, shape (nx,)
        State standardisation.
    u_scale : ndarray, shape (nu,)
        Inputs are divided by it.
    y_scale : ndarray, shape (ny,), optional
        Output targets are divided by it.
    """

    mean: np.ndarray
    std: np.ndarray
    u_scale: np.ndarray
    y_scale: np.ndarray | None = None


@dataclass
class TrainingResult:
    """What :func:`train_network` hands back: the network as float64 arrays, and its history."""

    weights: list[np.ndarray]
    biases: list[np.ndarray]
    history: list[tuple[int, float]]
    epochs_run: int


@dataclass(frozen=True)
class _ScaledWindows:
    """Windows of the rollout term as tensors: standardised and scaled states, scaled inputs."""

    Xs: torch.Tensor  # (M, H+1, nx), (x - mean) / std: what the network sees
    Xsc: torch.Tensor  # (M, H+1, nx), x / std: the state block of the lifted vector
    Us: torch.Tensor  # (M, H, nu), u / u_scale
    horizon: int  # steps of the rollout term, min(rollout_steps, H)


@dataclass(frozen=True)
class _ScaledData:
    """The training data as tensors in the units of the loss (see :class:`Scaling`)."""

    Xs: torch.Tensor  # (N, nx), (x - mean) / std
    Xns: torch.Tensor  # (N, nx), (x_next - mean) / std
    Xsc: torch.Tensor  # (N, nx), x / std
    Xnsc: torch.Tensor  # (N, nx), x_next / std
    Us: torch.Tensor  # (N, nu), u / u_scale
    Ys: torch.Tensor | None  # (N, ny), y / y_scale
    windows: _ScaledWindows | None

    @classmethod
    def build(
        cls, data: TrainingArrays, scaling: Scaling, training: MLPTraining, dtype: torch.dtype
    ) -> _ScaledData:
        """Scale ``data`` and convert it to tensors of ``dtype``; windows only when the rollout term is on."""
        mean, std, u_scale, y_scale = scaling.mean, scaling.std, scaling.u_scale, scaling.y_scale

        def tensor(a: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype)

        windows = None
        if data.windows is not None and training.rollout_weight > 0 and training.rollout_steps > 0:
            Xw, Uw = data.windows
            windows = _ScaledWindows(
                Xs=tensor((Xw - mean) / std),
                Xsc=tensor(Xw / std),
                Us=tensor(Uw / u_scale),
                horizon=min(training.rollout_steps, Uw.shape[1]),
            )
        Y = data.Y
        return cls(
            Xs=tensor((data.X - mean) / std),
            Xns=tensor((data.X_next - mean) / std),
            Xsc=tensor(data.X / std),
            Xnsc=tensor(data.X_next / std),
            Us=tensor(data.U / u_scale),
            Ys=None if Y is None or y_scale is None else tensor(Y / y_scale),
            windows=windows,
        )


class _Trainer:
    """One training run of a lifting network: the batch loss, the epochs, the best-epoch bookkeeping.

    All random draws (batch order, windows, window offsets) come from one numpy generator seeded with
    ``training.seed``, in a fixed order, so a run is reproducible to the last bit.
    """

    def __init__(
        self,
        net: torch.nn.Module,
        data: _ScaledData,
        training: MLPTraining,
        *,
        include_state: bool,
        ridge: float,
    ) -> None:
        self.net = net
        self.data = data
        self.include_state = include_state
        self.ridge = ridge
        self.huber_delta = training.huber_delta
        self.rollout_weight = training.rollout_weight
        self.epochs = training.epochs
        self.rng = np.random.default_rng(training.seed)
        self.optimiser = torch.optim.Adam(net.parameters(), lr=training.learning_rate)
        self.n = data.Xs.shape[0]
        self.nx = data.Xs.shape[1]
        batch = min(training.batch_size, self.n)
        self.n_batches = max(1, int(np.ceil(self.n / batch)))  # near-equal batches: no tiny remainder
        self.n_windows = 0 if data.windows is None else data.windows.Xs.shape[0]
        self.window_batch = min(self.n_windows, max(64, training.batch_size // 4))
        self.history: list[tuple[int, float]] = []
        self.epochs_run = 0
        self.best_loss = math.inf
        self.best_state = copy.deepcopy(net.state_dict())

    # ------------------------------------------------------------------ the loss

    def lifted(self, xs: torch.Tensor, xsc: torch.Tensor) -> torch.Tensor:
        """Lifted vector of standardised states ``xs`` (scaled states ``xsc`` first, when included)."""
        psi = self.net(xs)
        return torch.cat([xsc, psi], dim=-1) if self.include_state else psi

    def batch_loss(self, idx: np.ndarray) -> torch.Tensor:
        """Loss of the samples ``idx``: one-step residual, reconstruction, output and rollout terms."""
        d, delta, ridge = self.data, self.huber_delta, self.ridge
        t = torch.as_tensor(idx)
        z = self.lifted(d.Xs[t], d.Xsc[t])
        zn = self.lifted(d.Xns[t], d.Xnsc[t])
        u = d.Us[t]
        phi = torch.cat([z, u], dim=1)
        W = ridge_solve(phi, zn, ridge)
        nz = z.shape[1]
        A, B = W[:nz].T, W[nz:].T
        loss = pseudo_huber(torch.mean(torch.abs(zn - phi @ W)), delta)
        state_map = None
        if not self.include_state:
            state_map = ridge_solve(z, d.Xsc[t], ridge).T  # (nx, nz)
            recon = torch.mean(torch.abs(d.Xsc[t] - z @ state_map.T))
            loss = loss + pseudo_huber(recon, delta)
        if d.Ys is not None:
            Wy = ridge_solve(phi, d.Ys[t], ridge)
            loss = loss + pseudo_huber(torch.mean(torch.abs(d.Ys[t] - phi @ Wy)), delta)
        if d.windows is not None and d.windows.horizon > 0:
            loss = loss + self.rollout_weight * self.rollout_loss(d.windows, A, B, state_map)
        return loss

    def rollout_loss(
        self, windows: _ScaledWindows, A: torch.Tensor, B: torch.Tensor, state_map: torch.Tensor | None
    ) -> torch.Tensor:
        """Pseudo-Huber multi-step state error on a random batch of windows, at a random offset."""
        horizon = windows.horizon
        w = torch.as_tensor(self.rng.choice(self.n_windows, size=self.window_batch, replace=False))
        off = int(self.rng.integers(0, windows.Us.shape[1] - horizon + 1))
        z0 = self.lifted(windows.Xs[w, off], windows.Xsc[w, off])
        zs = rollout(z0, windows.Us[w, off : off + horizon], A, B)
        xs_pred = zs[..., : self.nx] if state_map is None else zs @ state_map.T
        err = torch.mean(torch.abs(xs_pred - windows.Xsc[w, off + 1 : off + 1 + horizon]))
        return pseudo_huber(err, self.huber_delta)

    # ------------------------------------------------------------------ the epochs

    def batches(self) -> list[np.ndarray]:
        """Sample indices of the batches of one epoch, in a fresh random order."""
        return np.array_split(self.rng.permutation(self.n), self.n_batches)

    def initial_loss(self) -> float:
        """Mean batch loss of the untrained network (no step taken)."""
        with torch.no_grad():
            initial = [float(self.batch_loss(idx)) for idx in self.batches()]
        return float(np.mean(initial))

    def epoch(self) -> list[float]:
        """One pass of Adam steps over the data; the batch losses, NaN for a skipped batch.

        Divergence guard: a batch whose least-squares fit is ill-conditioned can give a huge loss and
        gradient; a batch with a non-finite loss or one above ``SKIP_LOSS_FACTOR`` times the best
        epoch loss so far is skipped, and the gradients of the others are clipped.
        """
        losses = []
        for idx in self.batches():
            self.optimiser.zero_grad(set_to_none=True)
            loss = self.batch_loss(idx)
            value = float(loss.detach())
            if not math.isfinite(value) or value > SKIP_LOSS_FACTOR * max(self.best_loss, 1e-12):
                losses.append(math.nan)
            else:
                loss.backward()
                torch.nn.utils.clip_grad_norm_(self.net.parameters(), MAX_GRAD_NORM)
                self.optimiser.step()
                losses.append(value)
        return losses

    def record(self, epoch: int, mean_loss: float) -> None:
        """Append ``(epoch, mean_loss)`` to the history; keep the network when it is the best so far."""
        self.history.append((epoch, mean_loss))
        if math.isfinite(mean_loss) and mean_loss < self.best_loss:
            self.best_loss = mean_loss
            self.best_state = copy.deepcopy(self.net.state_dict())

    def run(self, on_epoch: Callable[[int, float], None] | None) -> None:
        """Evaluate the untrained network, train ``epochs`` epochs, and load the best epoch's network."""
        self.record(0, self.initial_loss())
        if on_epoch is not None:
            on_epoch(0, self.history[-1][1])
        for epoch in range(1, self.epochs + 1):
            losses = self.epoch()
            if losses:
                kept = [v for v in losses if math.isfinite(v)]
                self.record(epoch, float(np.mean(kept)) if kept else math.nan)
                self.epochs_run = epoch
                if on_epoch is not None:
                    on_epoch(epoch, self.history[-1][1])
        self.net.load_state_dict(self.best_state)


def train_network(
    data: TrainingArrays,
    scaling: Scaling,
    *,
    hidden: tuple[int, int],
    n_lift: int,
    training: MLPTraining,
    include_state: bool,
    ridge: float,
    on_epoch: Callable[[int, float], None] | None = None,
    dtype: torch.dtype = torch.float64,
) -> TrainingResult:
    """Train the lifting network with Adam (see the module docstring for the loss).

    Parameters
    ----------
    data : TrainingArrays
        States, inputs, successors, optional outputs and sequences.
    scaling : Scaling
        Scales of states, inputs and outputs.
    hidden, n_lift
        Network shape.
    training : MLPTraining
        Epochs, step size, batch size, loss settings and seed.
    include_state : bool
        Whether the lifted vector starts with the (scaled) state.
    ridge : float
        Tikhonov weight of the per-batch least squares (at least :data:`MIN_TRAINING_RIDGE`).
    on_epoch : callable, optional
        Called as ``on_epoch(epoch, mean_loss)`` after epoch 0 (the untrained network) and each epoch.
    dtype : torch.dtype
        Precision of the network and the loss. float64 by default: at these sizes it costs about the
        same as float32 on a CPU, keeps the per-batch least squares well conditioned, and makes the
        exported numpy lifting reproduce the trained network to rounding.

    Returns
    -------
    TrainingResult
        The network of the epoch with the lowest mean loss (the untrained one included), the history
        of every epoch.
    """
    scaled = _ScaledData.build(data, scaling, training, dtype)
    ridge = max(float(ridge), MIN_TRAINING_RIDGE)
    with torch.random.fork_rng(devices=[]):
        set_torch_seed(training.seed)
        net = make_torch_mlp(data.X.shape[1], hidden, n_lift, training.seed, dtype=dtype)
        trainer = _Trainer(net, scaled, training, include_state=include_state, ridge=ridge)
        trainer.run(on_epoch)
    net.eval()
    weights, biases = network_arrays(net)
    return TrainingResult(
        weights=weights, biases=biases, history=trainer.history, epochs_run=trainer.epochs_run
    )
