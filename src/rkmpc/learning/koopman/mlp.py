"""The lifting network :class:`MLPLifting`: a small ReLU network whose outputs are the learned features.

Inference is plain numpy (three matrix products); :meth:`MLPLifting.fit` trains the network with the
paper's loss through :mod:`rkmpc.learning.koopman.training`, which imports PyTorch (only then).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from typing import Any, ClassVar

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer
from rkmpc.learning.koopman.common import as_vector, check_input, standardisation
from rkmpc.learning.koopman.settings import MLPTraining
from rkmpc.learning.koopman.windows import consecutive_windows

__all__ = ["MLPLifting", "MLPTraining"]


class MLPLifting:
    """A lifting network trained with the paper's loss.

    ``psi(x) = W2 relu(W1 relu(W0 (x - mean) / std + b0) + b1) + b2``.

    Parameters
    ----------
    n_lift : int
        Number of learned features (network outputs).
    hidden : tuple of two int
        Widths of the two hidden layers.
    training : MLPTraining, optional
        Epochs, step size, batches, loss and seed; ``MLPTraining()`` when None.

    Attributes
    ----------
    weights_ : list of ndarray
        ``W0`` (h0, nx), ``W1`` (h1, h0), ``W2`` (n_lift, h1), laid out as in ``torch.nn.Linear``.
    biases_ : list of ndarray
        Shapes (h0,), (h1,), (n_lift,).
    mean_, std_ : ndarray, shape (nx,)
        Input standardisation (units of the state features).
    nx_ : int
        Number of state features.
    history_ : list of (int, float)
        ``(epoch, mean training loss)``; epoch 0 is the untrained network (empty when the weights
        were set, not trained).
    epochs_run_ : int
        Training epochs completed.

    Notes
    -----
    The standardisation is folded into the first layer once, so a call is three matrix products and
    two ``maximum`` operations.
    """

    name: ClassVar[str] = "mlp"

    def __init__(
        self, n_lift: int = 16, hidden: tuple[int, int] = (64, 64), training: MLPTraining | None = None
    ):
        self.n_lift = n_lift
        self.hidden = hidden
        self.training = training
        self.history_: list[tuple[int, float]] = []

    # ------------------------------------------------------------------ settings

    def get_params(self) -> dict[str, Any]:
        """Settings as plain JSON types (``kind`` first)."""
        return {
            "kind": self.name,
            "n_lift": self.n_lift,
            "hidden": list(self.hidden),
            "training": asdict(self._training()),
        }

    def _training(self) -> MLPTraining:
        return self.training if self.training is not None else MLPTraining()

    def validate(self) -> None:
        """Raise :class:`ParameterError` for bad settings."""
        hidden = self.hidden
        if (
            not isinstance(hidden, (tuple, list))
            or len(hidden) != 2
            or not all(is_integer(h, 1) for h in hidden)
        ):
            raise ParameterError(f"MLPLifting.hidden must be two positive integers, got {hidden!r}")
        if not is_integer(self.n_lift, 1):
            raise ParameterError(f"MLPLifting.n_lift must be an integer >= 1, got {self.n_lift!r}")
        if self.training is not None and not isinstance(self.training, MLPTraining):
            raise ParameterError(f"MLPLifting.training must be an MLPTraining, got {self.training!r}")

    def __repr__(self) -> str:
        hidden = tuple(self.hidden)
        return f"MLPLifting(n_lift={self.n_lift!r}, hidden={hidden!r}, training={self._training()!r})"

    # ------------------------------------------------------------------ learning

    def fit(
        self,
        X: np.ndarray,
        U: np.ndarray,
        X_next: np.ndarray,
        *,
        Y: np.ndarray | None = None,
        windows: tuple[np.ndarray, np.ndarray] | None = None,
        include_state: bool = True,
        ridge: float = 1e-6,
        on_epoch: Callable[[int, float], None] | None = None,
    ) -> MLPLifting:
        """Train the network on one-step data (see :mod:`rkmpc.learning.koopman.training`).

        Parameters
        ----------
        X, X_next : ndarray, shape (N, nx)
            States and successors (validated by the caller).
        U : ndarray, shape (N, nu)
            Inputs.
        Y : ndarray, shape (N, ny), optional
            Output targets; their reconstruction joins the loss.
        windows : tuple (Xw (M, H+1, nx), Uw (M, H, nu)), optional
            Sequences for the multi-step term; taken from runs of consecutive samples when omitted.
        include_state : bool
            Whether the lifted vector starts with the state itself.
        ridge : float
            Tikhonov weight of the per-batch least squares.
        on_epoch : callable, optional
            Progress callback ``on_epoch(epoch, mean_loss)``.

        Returns
        -------
        self
        """
        # torch is imported here only: loading and using a fitted lifting does not need it.
        try:
            from rkmpc.learning.koopman import training as torch_training
            from rkmpc.learning.koopman.torch_ops import torch_runtime
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError(
                "training a lifting network needs PyTorch: pip install 'rkmpc[train]' "
                "(torch==2.13.0; install that CPU build first, a looser pin pulls a CUDA build)"
            ) from exc

        self.validate()
        settings = self._training()
        if windows is None and settings.rollout_weight > 0 and settings.rollout_steps > 0:
            windows = consecutive_windows(X, U, X_next, settings.rollout_steps)
        mean, std = standardisation(X)
        _, u_scale = standardisation(U) if U.shape[1] else (None, np.ones(0))
        y_scale = None if Y is None else standardisation(Y)[1]
        data = torch_training.TrainingArrays(X=X, U=U, X_next=X_next, Y=Y, windows=windows)
        scaling = torch_training.Scaling(mean=mean, std=std, u_scale=u_scale, y_scale=y_scale)
        with torch_runtime():
            result = torch_training.train_network(
                data,
                scaling,
                hidden=(int(self.hidden[0]), int(self.hidden[1])),
                n_lift=int(self.n_lift),
                training=settings,
                include_state=include_state,
                ridge=ridge,
                on_epoch=on_epoch,
            )
        self.set_network(result.weights, result.biases, mean, std)
        self.history_ = result.history
        self.epochs_run_ = result.epochs_run
        return self

    def set_network(
        self,
        weights: Sequence[np.ndarray],
        biases: Sequence[np.ndarray],
        mean: np.ndarray,
        std: np.ndarray,
    ) -> MLPLifting:
        """Set the learned network directly (a trained or stored one) and return ``self``.

        Parameters
        ----------
        weights : sequence of three ndarray
            ``W0`` (h0, nx), ``W1`` (h1, h0), ``W2`` (n_lift, h1).
        biases : sequence of three ndarray
            Shapes (h0,), (h1,), (n_lift,).
        mean, std : ndarray, shape (nx,)
            The input standardisation; ``std`` must be positive.
        """
        if len(weights) != 3 or len(biases) != 3:
            raise ParameterError("MLPLifting needs exactly three layers (two hidden, one output)")
        ws = [np.array(w, dtype=float) for w in weights]
        bs = [np.array(b, dtype=float).reshape(-1) for b in biases]
        previous = ws[0].shape[1] if ws[0].ndim == 2 else -1
        for i, (w, b) in enumerate(zip(ws, bs, strict=True)):
            if w.ndim != 2 or w.shape[1] != previous or b.shape != (w.shape[0],):
                raise ParameterError(f"MLPLifting layer {i}: weight {w.shape}, bias {b.shape} do not chain")
            if not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
                raise ParameterError(f"MLPLifting layer {i}: weights must be finite")
            previous = w.shape[0]
        nx = ws[0].shape[1]
        mean_ = as_vector(mean, "mean", nx)
        std_ = as_vector(std, "std", nx)
        if np.any(std_ <= 0):
            raise ParameterError("std must be positive")
        self.weights_, self.biases_ = ws, bs
        self.mean_, self.std_ = mean_, std_
        self.nx_ = nx
        self.n_lift = ws[2].shape[0]
        self.hidden = (ws[0].shape[0], ws[1].shape[0])
        self.history_ = []
        self.epochs_run_ = 0
        # Fold (x - mean) / std into the first layer: W0' = W0 / std, b0' = b0 - W0' mean.
        self._w0 = ws[0] / std_
        self._b0 = bs[0] - self._w0 @ mean_
        return self

    # ------------------------------------------------------------------ inference

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Lift states, shape (n_samples, nx) or (nx,), in their original units."""
        if not hasattr(self, "weights_"):
            raise RuntimeError("this MLPLifting is not fitted yet: call fit() or set_network() first")
        X = check_input(X, self.nx_, "MLPLifting")
        w1, w2 = self.weights_[1], self.weights_[2]
        b1, b2 = self.biases_[1], self.biases_[2]
        if X.ndim == 1:
            h = np.maximum(self._w0 @ X + self._b0, 0.0)
            h = np.maximum(w1 @ h + b1, 0.0)
            return w2 @ h + b2
        h = np.maximum(X @ self._w0.T + self._b0, 0.0)
        h = np.maximum(h @ w1.T + b1, 0.0)
        return h @ w2.T + b2

    def to_arrays(self) -> dict[str, np.ndarray]:
        """All learned parameters as named arrays (keys ``mean``, ``std``, ``W0..W2``, ``b0..b2``)."""
        arrays = {"mean": self.mean_.copy(), "std": self.std_.copy()}
        for i, (w, b) in enumerate(zip(self.weights_, self.biases_, strict=True)):
            arrays[f"W{i}"] = w.copy()
            arrays[f"b{i}"] = b.copy()
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], training: MLPTraining | None = None) -> MLPLifting:
        """A fitted lifting from :meth:`to_arrays` output; raises ``KeyError`` for a missing array."""
        return cls(training=training).set_network(
            weights=[arrays[f"W{i}"] for i in range(3)],
            biases=[arrays[f"b{i}"] for i in range(3)],
            mean=arrays["mean"],
            std=arrays["std"],
        )
