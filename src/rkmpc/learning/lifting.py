"""Lifting functions psi: R^nx -> R^n_lift for the Koopman model.

Two kinds of dictionary are provided, both as plain-numpy inference objects so that lifting a
state at control time costs a few matrix-vector products and needs no torch:

* :class:`MLPLifting` -- a trained network (standardisation, two ReLU hidden layers, linear output),
  exported from torch with :func:`export_mlp`;
* :class:`RBFLifting` -- a fixed radial-basis dictionary in the spirit of Korda & Mezic (2018).

Both share the same interface: ``lifting(X)`` maps an array of states of shape (n_samples, nx) to
features of shape (n_samples, n_lift), or a single state of shape (nx,) to shape (n_lift,);
``to_arrays()`` / ``from_arrays()`` convert to and from a flat ``dict[str, ndarray]`` for storage.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from rkmpc.errors import ParameterError

if TYPE_CHECKING:  # pragma: no cover - typing only
    import torch

__all__ = ["RBF_KINDS", "MLPLifting", "RBFLifting", "export_mlp", "make_torch_mlp", "standardisation"]

RBF_KINDS = ("thin_plate", "gaussian")


def standardisation(X: np.ndarray, min_std: float = 1e-8) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and standard deviation of ``X``, shape (nx,) each.

    Features whose spread is below ``min_std`` (constant columns) get a standard deviation of 1 so that
    dividing by it is harmless.
    """
    X = np.asarray(X, dtype=float)
    mean = X.mean(axis=0)
    std = X.std(axis=0)
    std = np.where(std < min_std, 1.0, std)
    return mean, std


def _as_vector(values: np.ndarray | Sequence[float], name: str, size: int | None = None) -> np.ndarray:
    array = np.array(values, dtype=float).reshape(-1)
    if size is not None and array.shape != (size,):
        raise ParameterError(f"{name} must have shape ({size},), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} must be finite")
    return array


def _check_input(X: np.ndarray, nx: int, who: str) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim not in (1, 2) or X.shape[-1] != nx:
        raise ParameterError(f"{who}: expected states of shape (n_samples, {nx}) or ({nx},), got {X.shape}")
    return X


class MLPLifting:
    """Numpy inference copy of a trained lifting network.

    ``psi(x) = W2 relu(W1 relu(W0 (x - mean) / std + b0) + b1) + b2``.

    Parameters
    ----------
    weights : sequence of ndarray
        Three weight matrices ``W0`` (h0, nx), ``W1`` (h1, h0), ``W2`` (n_lift, h1), laid out as in
        ``torch.nn.Linear`` (output dimension first).
    biases : sequence of ndarray
        The three bias vectors, shapes (h0,), (h1,), (n_lift,).
    mean, std : ndarray, shape (nx,)
        Input standardisation, in the units of the state features; ``std`` must be positive.

    Notes
    -----
    The standardisation is folded into the first layer once at construction, so a call is three
    matrix products and two ``maximum`` operations.
    """

    name: ClassVar[str] = "mlp"

    def __init__(
        self,
        weights: Sequence[np.ndarray],
        biases: Sequence[np.ndarray],
        mean: np.ndarray,
        std: np.ndarray,
    ) -> None:
        if len(weights) != 3 or len(biases) != 3:
            raise ParameterError("MLPLifting needs exactly three layers (two hidden, one output)")
        self.weights = [np.array(w, dtype=float) for w in weights]
        self.biases = [np.array(b, dtype=float).reshape(-1) for b in biases]
        previous = self.weights[0].shape[1] if self.weights[0].ndim == 2 else -1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            if w.ndim != 2 or w.shape[1] != previous or b.shape != (w.shape[0],):
                raise ParameterError(f"MLPLifting layer {i}: weight {w.shape}, bias {b.shape} do not chain")
            if not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
                raise ParameterError(f"MLPLifting layer {i}: weights must be finite")
            previous = w.shape[0]
        self.nx = self.weights[0].shape[1]
        self.n_lift = self.weights[2].shape[0]
        self.mean = _as_vector(mean, "mean", self.nx)
        self.std = _as_vector(std, "std", self.nx)
        if np.any(self.std <= 0):
            raise ParameterError("std must be positive")
        # Fold (x - mean) / std into the first layer: W0' = W0 / std, b0' = b0 - W0' mean.
        self._w0 = self.weights[0] / self.std
        self._b0 = self.biases[0] - self._w0 @ self.mean

    @property
    def hidden(self) -> tuple[int, int]:
        """Widths of the two hidden layers."""
        return (self.weights[0].shape[0], self.weights[1].shape[0])

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Lift states.

        Parameters
        ----------
        X : ndarray, shape (n_samples, nx) or (nx,)
            States in their original units.

        Returns
        -------
        ndarray, shape (n_samples, n_lift) or (n_lift,)
        """
        X = _check_input(X, self.nx, "MLPLifting")
        w1, w2 = self.weights[1], self.weights[2]
        b1, b2 = self.biases[1], self.biases[2]
        if X.ndim == 1:
            h = np.maximum(self._w0 @ X + self._b0, 0.0)
            h = np.maximum(w1 @ h + b1, 0.0)
            return w2 @ h + b2
        h = np.maximum(X @ self._w0.T + self._b0, 0.0)
        h = np.maximum(h @ w1.T + b1, 0.0)
        return h @ w2.T + b2

    def to_arrays(self) -> dict[str, np.ndarray]:
        """All parameters as named arrays (keys ``mean``, ``std``, ``W0..W2``, ``b0..b2``)."""
        arrays = {"mean": self.mean.copy(), "std": self.std.copy()}
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            arrays[f"W{i}"] = w.copy()
            arrays[f"b{i}"] = b.copy()
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> MLPLifting:
        """Rebuild from :meth:`to_arrays` output; raises ``KeyError`` for a missing array."""
        return cls(
            weights=[arrays[f"W{i}"] for i in range(3)],
            biases=[arrays[f"b{i}"] for i in range(3)],
            mean=arrays["mean"],
            std=arrays["std"],
        )


class RBFLifting:
    """Fixed radial-basis dictionary.

    With standardised input ``s = (x - mean) / std`` and ``r_j = ||s - c_j|| / width``, feature ``j`` is

    * ``"thin_plate"``: ``r_j^2 log(r_j)`` (0 at ``r_j = 0``), as in Korda & Mezic (2018);
    * ``"gaussian"``: ``exp(-r_j^2)``.

    Parameters
    ----------
    centers : ndarray, shape (n_centers, nx)
        Centres in standardised coordinates.
    width : float
        Length scale in standardised units, positive.
    kind : {"thin_plate", "gaussian"}
        Radial function.
    mean, std : ndarray, shape (nx,), optional
        Input standardisation; default zero mean and unit spread.
    """

    name: ClassVar[str] = "rbf"

    def __init__(
        self,
        centers: np.ndarray,
        width: float = 1.0,
        kind: str = "thin_plate",
        mean: np.ndarray | None = None,
        std: np.ndarray | None = None,
    ) -> None:
        centers = np.array(centers, dtype=float)
        if centers.ndim != 2 or centers.shape[0] < 1 or centers.shape[1] < 1:
            raise ParameterError(f"centers must have shape (n_centers, nx), got {centers.shape}")
        if not np.all(np.isfinite(centers)):
            raise ParameterError("centers must be finite")
        if kind not in RBF_KINDS:
            raise ParameterError(f"kind must be one of {RBF_KINDS}, got {kind!r}")
        width = float(width)
        if not (np.isfinite(width) and width > 0):
            raise ParameterError(f"width must be positive, got {width}")
        self.centers = centers
        self.width = width
        self.kind = kind
        self.nx = centers.shape[1]
        self.n_lift = centers.shape[0]
        self.mean = np.zeros(self.nx) if mean is None else _as_vector(mean, "mean", self.nx)
        self.std = np.ones(self.nx) if std is None else _as_vector(std, "std", self.nx)
        if np.any(self.std <= 0):
            raise ParameterError("std must be positive")
        self._scale = 1.0 / (self.std * self.width)
        self._c = self.centers / self.width  # centres in the scaled coordinates
        self._c_sq = np.sum(self._c**2, axis=1)

    @classmethod
    def from_data(
        cls,
        X: np.ndarray,
        n_centers: int,
        seed: int = 0,
        *,
        kind: str = "thin_plate",
        method: str = "kmeans++",
        width: float | None = None,
    ) -> RBFLifting:
        """Choose centres from data.

        Parameters
        ----------
        X : ndarray, shape (n_samples, nx)
            States; also sets the standardisation.
        n_centers : int
            Number of centres (at most ``n_samples``).
        seed : int
            Seed of the random choice.
        kind : {"thin_plate", "gaussian"}
            Radial function.
        method : {"kmeans++", "random"}
            ``"random"``: a seeded random subset of the (standardised) samples; ``"kmeans++"``: the
            k-means++ seeding rule (each new centre drawn with probability proportional to the squared
            distance to the nearest centre so far), which spreads centres over the data.
        width : float, optional
            Length scale in standardised units; default half the median distance between centres
            (1.0 when there is a single centre).
        """
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[0] < 1:
            raise ParameterError(f"X must have shape (n_samples, nx), got {X.shape}")
        n_centers = int(n_centers)
        if not 1 <= n_centers <= X.shape[0]:
            raise ParameterError(f"n_centers must be in [1, {X.shape[0]}], got {n_centers}")
        mean, std = standardisation(X)
        S = (X - mean) / std
        rng = np.random.default_rng(seed)
        if method == "random":
            centers = S[rng.choice(S.shape[0], size=n_centers, replace=False)]
        elif method == "kmeans++":
            chosen = [int(rng.integers(S.shape[0]))]
            d2 = np.sum((S - S[chosen[0]]) ** 2, axis=1)
            for _ in range(1, n_centers):
                total = d2.sum()
                if total <= 0:  # all remaining points coincide with centres: pick any unused one
                    unused = np.setdiff1d(np.arange(S.shape[0]), chosen)
                    nxt = int(rng.choice(unused))
                else:
                    nxt = int(rng.choice(S.shape[0], p=d2 / total))
                chosen.append(nxt)
                d2 = np.minimum(d2, np.sum((S - S[nxt]) ** 2, axis=1))
            centers = S[chosen]
        else:
            raise ParameterError(f"method must be 'kmeans++' or 'random', got {method!r}")
        if width is None:
            if n_centers > 1:
                diff = centers[:, None, :] - centers[None, :, :]
                dist = np.sqrt(np.sum(diff**2, axis=-1))[np.triu_indices(n_centers, k=1)]
                median = float(np.median(dist))
                width = 0.5 * median if median > 0 else 1.0
            else:
                width = 1.0
        return cls(centers, width=width, kind=kind, mean=mean, std=std)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Lift states.

        Parameters
        ----------
        X : ndarray, shape (n_samples, nx) or (nx,)
            States in their original units.

        Returns
        -------
        ndarray, shape (n_samples, n_centers) or (n_centers,)
        """
        X = _check_input(X, self.nx, "RBFLifting")
        s = (X - self.mean) * self._scale
        # Squared scaled distances via |s|^2 - 2 s.c + |c|^2 (clipped: rounding can make it negative).
        r2 = np.sum(s * s, axis=-1, keepdims=X.ndim == 2) - 2.0 * (s @ self._c.T) + self._c_sq
        r2 = np.maximum(r2, 0.0)
        if self.kind == "gaussian":
            return np.exp(-r2)
        # r^2 log r = 0.5 r^2 log(r^2); the limit at r = 0 is 0.
        safe = np.where(r2 > 0.0, r2, 1.0)
        return 0.5 * r2 * np.log(safe)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """All parameters as named arrays (``centers``, ``width``, ``kind`` code, ``mean``, ``std``)."""
        return {
            "centers": self.centers.copy(),
            "width": np.array(self.width),
            "kind": np.array(RBF_KINDS.index(self.kind)),
            "mean": self.mean.copy(),
            "std": self.std.copy(),
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> RBFLifting:
        """Rebuild from :meth:`to_arrays` output; raises ``KeyError`` for a missing array."""
        code = int(np.asarray(arrays["kind"]).reshape(()))
        if not 0 <= code < len(RBF_KINDS):
            raise ParameterError(f"unknown RBF kind code {code}")
        return cls(
            centers=arrays["centers"],
            width=float(np.asarray(arrays["width"]).reshape(())),
            kind=RBF_KINDS[code],
            mean=arrays["mean"],
            std=arrays["std"],
        )


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

    Returns
    -------
    torch.nn.Sequential
        Expects inputs already standardised, shape (batch, nx); see :func:`export_mlp`.
    """
    import torch

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


def export_mlp(module: torch.nn.Module, mean: np.ndarray, std: np.ndarray) -> MLPLifting:
    """Copy a network made by :func:`make_torch_mlp` into a numpy :class:`MLPLifting` (float64).

    Parameters
    ----------
    module : torch.nn.Module
        Network with exactly three ``Linear`` layers separated by ReLUs, taking standardised inputs.
    mean, std : ndarray, shape (nx,)
        The standardisation the network was trained with.
    """
    import torch

    layers = [m for m in module.modules() if isinstance(m, torch.nn.Linear)]
    if len(layers) != 3:
        raise ParameterError(f"export_mlp expects three Linear layers, found {len(layers)}")
    weights = [layer.weight.detach().to(torch.float64).cpu().numpy().copy() for layer in layers]
    biases = []
    for layer in layers:
        if layer.bias is None:
            biases.append(np.zeros(layer.out_features))
        else:
            biases.append(layer.bias.detach().to(torch.float64).cpu().numpy().copy())
    return MLPLifting(weights, biases, mean, std)
