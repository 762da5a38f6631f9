"""The radial-basis dictionary :class:`RBFLifting`: fixed features around centres picked from the data.

In the spirit of Korda & Mezic (2018) (plain EDMD); plain numpy, no training.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, require_choice
from rkmpc.learning.koopman.common import as_vector, check_input, standardisation

__all__ = ["RBF_KINDS", "RBF_METHODS", "RBFLifting"]

#: Radial functions of :class:`RBFLifting` (their index is the ``kind`` code of :meth:`RBFLifting.to_arrays`).
RBF_KINDS = ("thin_plate", "gaussian")
#: Ways of choosing the centres.
RBF_METHODS = ("kmeans++", "random")


class RBFLifting:
    """Fixed radial-basis dictionary with centres chosen from the data.

    With standardised input ``s = (x - mean) / std`` and ``r_j = ||s - c_j|| / width``, feature ``j`` is

    * ``"thin_plate"``: ``r_j^2 log(r_j)`` (0 at ``r_j = 0``), as in Korda & Mezic (2018);
    * ``"gaussian"``: ``exp(-r_j^2)``.

    Parameters
    ----------
    n_centers : int
        Number of centres (at most the number of samples).
    kind : {"thin_plate", "gaussian"}
        Radial function.
    seed : int
        Seed of the random choice of centres.
    method : {"kmeans++", "random"}
        ``"random"``: a seeded random subset of the (standardised) samples; ``"kmeans++"``: the
        k-means++ seeding rule (each new centre drawn with probability proportional to the squared
        distance to the nearest centre so far), which spreads centres over the data.
    width : float, optional
        Length scale in standardised units; default half the median distance between centres
        (1.0 when there is a single centre).

    Attributes
    ----------
    centers_ : ndarray, shape (n_centers, nx)
        Centres in standardised coordinates.
    width_ : float
        Length scale used.
    mean_, std_ : ndarray, shape (nx,)
        Input standardisation.
    nx_ : int
        Number of state features.
    """

    name: ClassVar[str] = "rbf"

    def __init__(
        self,
        n_centers: int = 32,
        kind: str = "thin_plate",
        seed: int = 0,
        method: str = "kmeans++",
        width: float | None = None,
    ) -> None:
        self.n_centers = n_centers
        self.kind = kind
        self.seed = seed
        self.method = method
        self.width = width

    def get_params(self) -> dict[str, Any]:
        """Settings as plain JSON types (``kind`` of lifting first, then the radial function)."""
        return {
            "kind": self.name,
            "n_centers": self.n_centers,
            "rbf_kind": self.kind,
            "seed": self.seed,
            "method": self.method,
            "width": self.width,
        }

    def validate(self) -> None:
        """Raise :class:`ParameterError` for bad settings."""
        if not is_integer(self.n_centers, 1):
            raise ParameterError(f"RBFLifting.n_centers must be an integer >= 1, got {self.n_centers!r}")
        require_choice(self, "kind", RBF_KINDS)
        if not is_integer(self.seed, 0):
            raise ParameterError(f"RBFLifting.seed must be an integer >= 0, got {self.seed!r}")
        require_choice(self, "method", RBF_METHODS)
        if self.width is not None and not (np.isfinite(self.width) and self.width > 0):
            raise ParameterError(f"RBFLifting.width must be positive or None, got {self.width!r}")

    def __repr__(self) -> str:
        return f"RBFLifting(n_centers={self.n_centers!r}, kind={self.kind!r}, seed={self.seed!r})"

    @property
    def n_lift(self) -> int:
        """Number of features (centres)."""
        return int(self.centers_.shape[0]) if hasattr(self, "centers_") else int(self.n_centers)

    def fit(self, X: np.ndarray, *_: Any, **__: Any) -> RBFLifting:
        """Choose the centres and the standardisation from states ``X`` (n_samples, nx); returns ``self``."""
        self.validate()
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[0] < 1:
            raise ParameterError(f"X must have shape (n_samples, nx), got {X.shape}")
        n_centers = int(self.n_centers)
        if n_centers > X.shape[0]:
            raise ParameterError(f"n_centers={n_centers} exceeds the {X.shape[0]} samples")
        mean, std = standardisation(X)
        S = (X - mean) / std
        rng = np.random.default_rng(self.seed)
        if self.method == "random":
            centers = S[rng.choice(S.shape[0], size=n_centers, replace=False)]
        else:
            chosen = [int(rng.integers(S.shape[0]))]
            d2 = np.sum((S - S[chosen[0]]) ** 2, axis=1)
            for _k in range(1, n_centers):
                total = d2.sum()
                if total <= 0:  # all remaining points coincide with centres: pick any unused one
                    unused = np.setdiff1d(np.arange(S.shape[0]), chosen)
                    nxt = int(rng.choice(unused))
                else:
                    nxt = int(rng.choice(S.shape[0], p=d2 / total))
                chosen.append(nxt)
                d2 = np.minimum(d2, np.sum((S - S[nxt]) ** 2, axis=1))
            centers = S[chosen]
        width = self.width
        if width is None:
            width = 1.0
            if n_centers > 1:
                diff = centers[:, None, :] - centers[None, :, :]
                dist = np.sqrt(np.sum(diff**2, axis=-1))[np.triu_indices(n_centers, k=1)]
                median = float(np.median(dist))
                width = 0.5 * median if median > 0 else 1.0
        return self.set_centers(centers, width, mean, std)

    def set_centers(
        self, centers: np.ndarray, width: float, mean: np.ndarray | None = None, std: np.ndarray | None = None
    ) -> RBFLifting:
        """Set the dictionary directly (centres in standardised coordinates) and return ``self``."""
        centers = np.array(centers, dtype=float)
        if centers.ndim != 2 or centers.shape[0] < 1 or centers.shape[1] < 1:
            raise ParameterError(f"centers must have shape (n_centers, nx), got {centers.shape}")
        if not np.all(np.isfinite(centers)):
            raise ParameterError("centers must be finite")
        if self.kind not in RBF_KINDS:
            raise ParameterError(f"kind must be one of {RBF_KINDS}, got {self.kind!r}")
        width = float(width)
        if not (np.isfinite(width) and width > 0):
            raise ParameterError(f"width must be positive, got {width}")
        nx = centers.shape[1]
        self.centers_, self.width_, self.nx_ = centers, width, nx
        self.mean_ = np.zeros(nx) if mean is None else as_vector(mean, "mean", nx)
        self.std_ = np.ones(nx) if std is None else as_vector(std, "std", nx)
        if np.any(self.std_ <= 0):
            raise ParameterError("std must be positive")
        self._scale = 1.0 / (self.std_ * width)
        self._c = centers / width  # centres in the scaled coordinates
        self._c_sq = np.sum(self._c**2, axis=1)
        return self

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Lift states, shape (n_samples, nx) or (nx,), in their original units."""
        if not hasattr(self, "centers_"):
            raise RuntimeError("this RBFLifting is not fitted yet: call fit() or set_centers() first")
        X = check_input(X, self.nx_, "RBFLifting")
        s = (X - self.mean_) * self._scale
        # Squared scaled distances via |s|^2 - 2 s.c + |c|^2 (clipped: rounding can make it negative).
        r2 = np.sum(s * s, axis=-1, keepdims=X.ndim == 2) - 2.0 * (s @ self._c.T) + self._c_sq
        r2 = np.maximum(r2, 0.0)
        if self.kind == "gaussian":
            return np.exp(-r2)
        # r^2 log r = 0.5 r^2 log(r^2); the limit at r = 0 is 0.
        safe = np.where(r2 > 0.0, r2, 1.0)
        return 0.5 * r2 * np.log(safe)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Learned parameters as named arrays (``centers``, ``width``, ``kind`` code, ``mean``, ``std``)."""
        return {
            "centers": self.centers_.copy(),
            "width": np.array(self.width_),
            "kind": np.array(RBF_KINDS.index(self.kind)),
            "mean": self.mean_.copy(),
            "std": self.std_.copy(),
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], seed: int = 0) -> RBFLifting:
        """A fitted dictionary from :meth:`to_arrays` output; raises ``KeyError`` for a missing array."""
        code = int(np.asarray(arrays["kind"]).reshape(()))
        if not 0 <= code < len(RBF_KINDS):
            raise ParameterError(f"unknown RBF kind code {code}")
        centers = np.asarray(arrays["centers"])
        lifting = cls(
            n_centers=int(centers.shape[0]) if centers.ndim == 2 else 1, kind=RBF_KINDS[code], seed=seed
        )
        return lifting.set_centers(
            centers, float(np.asarray(arrays["width"]).reshape(())), mean=arrays["mean"], std=arrays["std"]
        )
