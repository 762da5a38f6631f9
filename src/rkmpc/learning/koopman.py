"""Lifted linear (Koopman) model of a controlled system, learned from data.

The model (paper Sec. III-B and IV-B) is

.. code-block:: text

    z_k     = [x_k (if include_state), psi(x_k)]      lifted state, size nz
    z_{k+1} = A z_k + B u_k
    y_k     = C z_k + D u_k

with ``x`` the state features (nx), ``u`` the input (nu) and ``y`` the output (ny): by default ``y = x``
(``D = 0``; ``C`` selects ``x`` from ``z`` when the state is part of it, otherwise it is regressed), or any
target ``Y`` passed to :meth:`KoopmanModel.fit`. ``A, B`` are the closed-form least-squares solution
``[A, B] = Z_next [Z; U]^+`` (optionally ridge-regularised), ``C, D`` likewise.

The dictionary ``psi`` is

* ``"mlp"``: a two-hidden-layer ReLU network trained with the paper's pseudo-Huber loss on the one-step
  lifted residual, with ``A, B`` recomputed in closed form on each batch (see
  :mod:`rkmpc.learning.training`);
* ``"rbf"``: a fixed radial-basis dictionary (no training, plain EDMD);
* ``"none"``: no dictionary, ``z = x`` (plain DMD with inputs; a linear baseline).

The network and the least-squares fit only know the states they were trained on. Outside that range
their output is an extrapolation, and on nearly constant data a wild one: on the IMS oval the car
drives at its top speed almost everywhere, the speed feature of the residual model spans 1e-5 m/s,
and a speed 1 cm/s below it made the model predict a 0.46 m/s, 0.009 rad residual. So the model
records the range of its training states (``x_min_``, ``x_max_``) and, with ``clip_inputs`` (the
default), :meth:`KoopmanModel.lift` clips a state into that range before lifting it: outside the
data the model answers as at the nearest edge of what it has seen.

A fitted model is stored as one ``.npz`` file (:meth:`KoopmanModel.save` / :meth:`KoopmanModel.load`).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
import zipfile
import zlib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.errors import InputFileError, ParameterError
from rkmpc.learning.edmd import fit_dynamics, fit_output
from rkmpc.learning.lifting import RBF_KINDS, MLPLifting, RBFLifting, standardisation
from rkmpc.sim.log import json_default

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "LIFTING_KINDS", "KoopmanModel"]

FORMAT_NAME = "rkmpc-koopman"
FORMAT_VERSION = 2
#: Format versions :meth:`KoopmanModel.load` reads (version 1 has no state range: nothing is clipped).
READABLE_VERSIONS = (1, 2)
LIFTING_KINDS = ("mlp", "rbf", "none")
_MATRICES = ("A", "B", "C", "D", "Cx")

Lifting = MLPLifting | RBFLifting


def _data(value: Any, name: str, ndim: int) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim != ndim:
        raise ParameterError(f"{name} must be a {ndim}-D array, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} contains NaN or infinite values")
    return array


class KoopmanModel:
    """Lifted linear model ``z+ = A z + B u``, ``y = C z + D u`` with a learned or fixed lifting.

    Parameters
    ----------
    lifting : {"mlp", "rbf", "none"}
        Dictionary kind (see the module docstring).
    n_lift : int
        Number of learned features for ``"mlp"``.
    hidden : tuple of two int
        Hidden layer widths of the network.
    include_state : bool
        Whether ``x`` itself is the first block of ``z`` (required for ``"none"``).
    n_centers : int
        Number of radial basis functions for ``"rbf"``.
    rbf_kind : {"thin_plate", "gaussian"}
        Radial function for ``"rbf"``.
    epochs : int
        Maximum number of passes over the data (``"mlp"``).
    learning_rate : float
        Adam step size.
    batch_size : int
        Samples per batch; ``A, B`` are solved on each batch, so it should be well above ``nz + nu``.
    huber_delta : float
        ``delta`` of the pseudo-Huber loss (scaled units).
    rollout_steps : int
        Horizon of the multi-step term of the loss.
    rollout_weight : float
        Weight of the multi-step term (0 disables it).
    ridge : float
        Tikhonov weight of the least-squares fits, dimensionless (see
        :func:`rkmpc.learning.edmd.ridge_lstsq`).
    seed : int
        Seed of all randomness (network initialisation, batches, RBF centres).
    max_seconds : float or None
        Wall-clock budget of :meth:`fit`; training stops after the batch that exceeds it
        (``stopped_early_`` is then True). None: no limit.
    clip_inputs : bool
        Whether :meth:`lift` clips a state into the range of the training states first
        (``x_min_ .. x_max_``), so that the model never extrapolates.

    Attributes
    ----------
    A_ : ndarray, shape (nz, nz)
    B_ : ndarray, shape (nz, nu)
    C_ : ndarray, shape (ny, nz)
    D_ : ndarray, shape (ny, nu)
    Cx_ : ndarray, shape (nx, nz)
        Map from lifted state to state features (selection when ``include_state``).
    x_min_, x_max_ : ndarray, shape (nx,)
        Smallest and largest value of each state feature in the training data (``X`` and
        ``X_next``); infinite for a model read from a version-1 file.
    lifting_ : MLPLifting, RBFLifting or None
        The dictionary ``psi`` (None for ``"none"``).
    n_lifted_ : int
        ``nz``.
    nx_, nu_, ny_ : int
        Sizes of state, input and output.
    output_is_state_ : bool
        True when no ``Y`` was given (``y = x``).
    history_ : list of (int, float)
        ``(epoch, mean training loss)``; epoch 0 is the untrained network. Empty unless ``"mlp"``.
    fit_time_s_ : float
        Wall-clock duration of :meth:`fit`, seconds.
    stopped_early_ : bool
        Whether training was cut by ``max_seconds``.
    epochs_run_ : int
        Training epochs completed (0 unless ``"mlp"``).
    metadata_ : dict
        Caller metadata read by :meth:`load` (empty after :meth:`fit`).
    """

    def __init__(
        self,
        *,
        lifting: str = "mlp",
        n_lift: int = 16,
        hidden: tuple[int, int] = (64, 64),
        include_state: bool = True,
        n_centers: int = 32,
        rbf_kind: str = "thin_plate",
        epochs: int = 300,
        learning_rate: float = 1e-3,
        batch_size: int = 1024,
        huber_delta: float = 1.0,
        rollout_steps: int = 10,
        rollout_weight: float = 0.1,
        ridge: float = 1e-6,
        seed: int = 0,
        max_seconds: float | None = 60.0,
        clip_inputs: bool = True,
    ) -> None:
        self.lifting = lifting
        self.n_lift = n_lift
        self.hidden = hidden
        self.include_state = include_state
        self.n_centers = n_centers
        self.rbf_kind = rbf_kind
        self.epochs = epochs
        self.learning_rate = learning_rate
        self.batch_size = batch_size
        self.huber_delta = huber_delta
        self.rollout_steps = rollout_steps
        self.rollout_weight = rollout_weight
        self.ridge = ridge
        self.seed = seed
        self.max_seconds = max_seconds
        self.clip_inputs = clip_inputs

    _PARAM_NAMES = (
        "lifting",
        "n_lift",
        "hidden",
        "include_state",
        "n_centers",
        "rbf_kind",
        "epochs",
        "learning_rate",
        "batch_size",
        "huber_delta",
        "rollout_steps",
        "rollout_weight",
        "ridge",
        "seed",
        "max_seconds",
        "clip_inputs",
    )

    def get_params(self) -> dict[str, Any]:
        """Constructor parameters as a dict (``hidden`` as a tuple)."""
        params = {name: getattr(self, name) for name in self._PARAM_NAMES}
        params["hidden"] = tuple(params["hidden"])
        return params

    def __repr__(self) -> str:
        defaults = KoopmanModel()
        changed = [
            f"{name}={getattr(self, name)!r}"
            for name in self._PARAM_NAMES
            if getattr(self, name) != getattr(defaults, name)
        ]
        return f"KoopmanModel({', '.join(changed)})"

    # ------------------------------------------------------------------ validation

    def _validate_params(self) -> None:
        def positive_int(name: str, minimum: int = 1) -> None:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
                raise ParameterError(f"{name} must be an integer >= {minimum}, got {value!r}")

        def positive_float(name: str, allow_zero: bool = False) -> None:
            value = getattr(self, name)
            ok = isinstance(value, (int, float, np.floating)) and not isinstance(value, bool)
            ok = ok and np.isfinite(value) and (value >= 0 if allow_zero else value > 0)
            if not ok:
                bound = ">= 0" if allow_zero else "> 0"
                raise ParameterError(f"{name} must be a finite number {bound}, got {value!r}")

        if self.lifting not in LIFTING_KINDS:
            raise ParameterError(f"lifting must be one of {LIFTING_KINDS}, got {self.lifting!r}")
        if self.rbf_kind not in RBF_KINDS:
            raise ParameterError(f"rbf_kind must be one of {RBF_KINDS}, got {self.rbf_kind!r}")
        for flag in ("include_state", "clip_inputs"):
            if not isinstance(getattr(self, flag), bool):
                raise ParameterError(f"{flag} must be a bool, got {getattr(self, flag)!r}")
        if self.lifting == "none" and not self.include_state:
            raise ParameterError("lifting='none' needs include_state=True (otherwise z would be empty)")
        hidden = self.hidden
        if (
            not isinstance(hidden, (tuple, list))
            or len(hidden) != 2
            or not all(isinstance(h, (int, np.integer)) and not isinstance(h, bool) for h in hidden)
            or min(hidden) < 1
        ):
            raise ParameterError(f"hidden must be two positive integers, got {hidden!r}")
        for name in ("n_lift", "n_centers", "epochs", "batch_size"):
            positive_int(name)
        for name in ("rollout_steps", "seed"):
            positive_int(name, minimum=0)
        for name in ("learning_rate", "huber_delta"):
            positive_float(name)
        for name in ("rollout_weight", "ridge"):
            positive_float(name, allow_zero=True)
        if self.max_seconds is not None:
            positive_float("max_seconds")

    # ------------------------------------------------------------------ fitting

    def fit(
        self,
        X: np.ndarray,
        U: np.ndarray,
        X_next: np.ndarray,
        *,
        Y: np.ndarray | None = None,
        windows: tuple[np.ndarray, np.ndarray] | None = None,
        on_epoch: Callable[[int, float], None] | None = None,
    ) -> KoopmanModel:
        """Learn the lifting (``"mlp"``) and the matrices from one-step data.

        Parameters
        ----------
        X : ndarray, shape (N, nx)
            States ``x_k`` (state-feature units).
        U : ndarray, shape (N, nu)
            Inputs ``u_k``.
        X_next : ndarray, shape (N, nx)
            Successors ``x_{k+1}``.
        Y : ndarray, shape (N, ny), optional
            Output targets ``y_k``; default ``y = x``.
        windows : tuple (Xw, Uw), optional
            Consecutive sequences, ``Xw`` (M, H+1, nx) and ``Uw`` (M, H, nu), for the multi-step term of
            the loss. When omitted, windows of ``rollout_steps`` transitions are taken from runs of
            consecutive samples in ``X, X_next`` (``X_next[k] == X[k+1]``), if any.
        on_epoch : callable, optional
            Progress callback ``on_epoch(epoch, mean_loss)`` (``"mlp"`` only).

        Returns
        -------
        self
        """
        self._validate_params()
        X = _data(X, "X", 2)
        U = _data(U, "U", 2)
        X_next = _data(X_next, "X_next", 2)
        n, nx = X.shape
        if X_next.shape != X.shape:
            raise ParameterError(f"X_next has shape {X_next.shape}, X has {X.shape}")
        if U.shape[0] != n:
            raise ParameterError(f"U has {U.shape[0]} samples, X has {n}")
        if n < 2 or nx < 1:
            raise ParameterError(f"need at least 2 samples of at least 1 feature, got X of shape {X.shape}")
        nu = U.shape[1]
        if Y is not None:
            Y = _data(Y, "Y", 2)
            if Y.shape[0] != n:
                raise ParameterError(f"Y has {Y.shape[0]} samples, X has {n}")
        if windows is not None:
            if len(windows) != 2:
                raise ParameterError("windows must be a pair (Xw, Uw)")
            Xw = _data(windows[0], "windows[0]", 3)
            Uw = _data(windows[1], "windows[1]", 3)
            if Xw.shape[0] != Uw.shape[0] or Xw.shape[1] != Uw.shape[1] + 1 or Xw.shape[2] != nx:
                raise ParameterError(
                    f"windows must have shapes (M, H+1, {nx}) and (M, H, {nu}), got {Xw.shape} and {Uw.shape}"
                )
            if Uw.shape[2] != nu or Uw.shape[1] < 1 or Uw.shape[0] < 1:
                raise ParameterError(f"windows[1] must have shape (M, H>=1, {nu}), got {Uw.shape}")
            windows = (Xw, Uw)

        start = time.perf_counter()
        deadline = None if self.max_seconds is None else start + float(self.max_seconds)
        mean, std = standardisation(X)
        self.history_: list[tuple[int, float]] = []
        self.stopped_early_ = False
        self.epochs_run_ = 0
        self.metadata_: dict[str, Any] = {}
        lifting: Lifting | None
        if self.lifting == "none":
            lifting = None
        elif self.lifting == "rbf":
            if self.n_centers > n:
                raise ParameterError(f"n_centers={self.n_centers} exceeds the {n} samples")
            lifting = RBFLifting.from_data(X, self.n_centers, self.seed, kind=self.rbf_kind)
        else:
            lifting = self._train_mlp(X, U, X_next, Y, windows, mean, std, deadline, on_epoch)
        self.lifting_ = lifting
        self.nx_, self.nu_ = nx, nu
        self.x_min_ = np.minimum(X.min(axis=0), X_next.min(axis=0))
        self.x_max_ = np.maximum(X.max(axis=0), X_next.max(axis=0))

        # Final least squares on all data with the final lifting, float64.
        Z = self._lift(X)
        Z_next = self._lift(X_next)
        self.A_, self.B_ = fit_dynamics(Z, U, Z_next, ridge=self.ridge)
        nz = Z.shape[1]
        if self.include_state:
            self.Cx_ = np.eye(nx, nz)
        else:
            self.Cx_, _ = fit_output(Z, None, X, ridge=self.ridge)
        self.output_is_state_ = Y is None
        if Y is None:
            self.C_ = self.Cx_.copy()
            self.D_ = np.zeros((nx, nu))
        else:
            self.C_, self.D_ = fit_output(Z, U, Y, ridge=self.ridge)
        self.n_lifted_ = nz
        self.ny_ = self.C_.shape[0]
        self.fit_time_s_ = time.perf_counter() - start
        return self

    def _train_mlp(
        self,
        X: np.ndarray,
        U: np.ndarray,
        X_next: np.ndarray,
        Y: np.ndarray | None,
        windows: tuple[np.ndarray, np.ndarray] | None,
        mean: np.ndarray,
        std: np.ndarray,
        deadline: float | None,
        on_epoch: Callable[[int, float], None] | None,
    ) -> MLPLifting:
        # torch is imported here only: loading and using a fitted model does not need it.
        from rkmpc.learning.lifting import export_mlp
        from rkmpc.learning.training import consecutive_windows, torch_runtime, train_lifting

        if windows is None and self.rollout_weight > 0 and self.rollout_steps > 0:
            windows = consecutive_windows(X, U, X_next, self.rollout_steps)
        _, u_scale = standardisation(U) if U.shape[1] else (None, np.ones(0))
        y_scale = None if Y is None else standardisation(Y)[1]
        with torch_runtime():
            result = train_lifting(
                X,
                U,
                X_next,
                mean=mean,
                std=std,
                u_scale=u_scale,
                Y=Y,
                y_scale=y_scale,
                windows=windows,
                include_state=self.include_state,
                hidden=(int(self.hidden[0]), int(self.hidden[1])),
                n_lift=int(self.n_lift),
                epochs=int(self.epochs),
                learning_rate=float(self.learning_rate),
                batch_size=int(self.batch_size),
                huber_delta=float(self.huber_delta),
                rollout_steps=int(self.rollout_steps),
                rollout_weight=float(self.rollout_weight),
                ridge=float(self.ridge),
                seed=int(self.seed),
                deadline=deadline,
                on_epoch=on_epoch,
            )
        self.history_ = result.history
        self.stopped_early_ = result.stopped_early
        self.epochs_run_ = result.epochs_run
        return export_mlp(result.net, mean, std)

    # ------------------------------------------------------------------ inference

    def _check_fitted(self) -> None:
        if not hasattr(self, "A_"):
            raise RuntimeError("this KoopmanModel is not fitted yet: call fit() or load() first")

    def lift(self, X: np.ndarray) -> np.ndarray:
        """Lifted state ``z = [x, psi(x)]``, of ``x`` clipped into the training range when ``clip_inputs``.

        Parameters
        ----------
        X : ndarray, shape (n, nx) or (nx,)

        Returns
        -------
        ndarray, shape (n, nz) or (nz,)
        """
        self._check_fitted()
        X = np.asarray(X, dtype=float)
        if X.ndim not in (1, 2) or X.shape[-1] != self.nx_:
            raise ParameterError(f"lift: expected shape (n, {self.nx_}) or ({self.nx_},), got {X.shape}")
        if self.clip_inputs:
            X = np.minimum(np.maximum(X, self.x_min_), self.x_max_)
        return self._lift(X)

    def _lift(self, X: np.ndarray) -> np.ndarray:
        if self.lifting_ is None:
            return X.copy()
        psi = self.lifting_(X)
        if not self.include_state:
            return psi
        return np.concatenate((X, psi), axis=-1)

    def step(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One step ``z_{k+1} = A z_k + B u_k``; ``z`` (nz,) or (n, nz), ``u`` (nu,) or (n, nu)."""
        return np.asarray(z) @ self.A_.T + np.asarray(u) @ self.B_.T

    def output(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Output ``y_k = C z_k + D u_k``; ``z`` (nz,) or (n, nz), ``u`` (nu,) or (n, nu)."""
        return np.asarray(z) @ self.C_.T + np.asarray(u) @ self.D_.T

    def _rollout(self, Z0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """Lifted states ``z_0 .. z_H``, shape (M, H+1, nz), from ``Z0`` (M, nz) and ``U`` (M, H, nu)."""
        M, H = U.shape[0], U.shape[1]
        Zs = np.empty((M, H + 1, Z0.shape[1]))
        Zs[:, 0] = Z0
        At, Bt = self.A_.T, self.B_.T
        for k in range(H):
            Zs[:, k + 1] = Zs[:, k] @ At + U[:, k] @ Bt
        return Zs

    def _check_inputs(self, U: np.ndarray, ndim: int, name: str) -> np.ndarray:
        U = np.asarray(U, dtype=float)
        if U.ndim != ndim or U.shape[-1] != self.nu_:
            raise ParameterError(
                f"{name} must be a {ndim}-D array with {self.nu_} inputs last, got {U.shape}"
            )
        return U

    def predict(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """Outputs along an open-loop input sequence.

        Parameters
        ----------
        x0 : ndarray, shape (nx,)
            Initial state (lifted once).
        U : ndarray, shape (H, nu)
            Inputs ``u_0 .. u_{H-1}``.

        Returns
        -------
        ndarray, shape (H, ny)
            ``y_k = C z_k + D u_k`` for ``k = 0 .. H-1``.
        """
        self._check_fitted()
        U = self._check_inputs(U, 2, "U")
        Zs = self._rollout(self.lift(np.asarray(x0, dtype=float))[None, :], U[None])[0]
        return Zs[:-1] @ self.C_.T + U @ self.D_.T

    def predict_states(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """State features along an open-loop input sequence.

        Parameters
        ----------
        x0 : ndarray, shape (nx,)
        U : ndarray, shape (H, nu)

        Returns
        -------
        ndarray, shape (H+1, nx)
            ``x_0 .. x_H`` as read from the lifted state through ``Cx_`` (row 0 is ``x0`` itself when
            ``include_state``).
        """
        self._check_fitted()
        U = self._check_inputs(U, 2, "U")
        Zs = self._rollout(self.lift(np.asarray(x0, dtype=float))[None, :], U[None])[0]
        return Zs @ self.Cx_.T

    def multi_step_error(self, Xw: np.ndarray, Uw: np.ndarray, Yw: np.ndarray | None = None) -> np.ndarray:
        """Mean prediction-error norm per horizon step on held-out sequences.

        Each sequence is predicted open loop from its first state.

        Parameters
        ----------
        Xw : ndarray, shape (M, H+1, nx)
            True states ``x_0 .. x_H``.
        Uw : ndarray, shape (M, H, nu)
            Inputs ``u_0 .. u_{H-1}``.
        Yw : ndarray, shape (M, H, ny), optional
            True outputs ``y_0 .. y_{H-1}``; when given, output errors are reported instead of state errors.

        Returns
        -------
        ndarray, shape (H,)
            Without ``Yw``: entry ``k`` is the mean over sequences of ``||x_{k+1} - x_hat_{k+1}||`` (units
            of the state features). With ``Yw``: mean of ``||y_k - y_hat_k||``.
        """
        self._check_fitted()
        Xw = _data(Xw, "Xw", 3)
        Uw = self._check_inputs(Uw, 3, "Uw")
        if Xw.shape[0] != Uw.shape[0] or Xw.shape[1] != Uw.shape[1] + 1 or Xw.shape[2] != self.nx_:
            raise ParameterError(f"Xw {Xw.shape} and Uw {Uw.shape} must be (M, H+1, {self.nx_}), (M, H, nu)")
        Zs = self._rollout(self.lift(Xw[:, 0]), Uw)
        if Yw is None:
            err = Zs[:, 1:] @ self.Cx_.T - Xw[:, 1:]
        else:
            Yw = _data(Yw, "Yw", 3)
            if Yw.shape != (*Uw.shape[:2], self.ny_):
                raise ParameterError(f"Yw must have shape {(*Uw.shape[:2], self.ny_)}, got {Yw.shape}")
            err = Zs[:, :-1] @ self.C_.T + Uw @ self.D_.T - Yw
        return np.linalg.norm(err, axis=-1).mean(axis=0)

    # ------------------------------------------------------------------ storage

    def save(self, path: str | Path, *, metadata: Mapping[str, Any] | None = None) -> None:
        """Write the fitted model to one ``.npz`` file (temporary file in the same folder, then renamed).

        Parameters
        ----------
        path : str or Path
            Destination, written as given (no suffix is added).
        metadata : mapping, optional
            JSON-serialisable caller information (data hash, package version, ...), stored as is.
        """
        self._check_fitted()
        path = Path(path)
        kind = "none" if self.lifting_ is None else self.lifting_.name
        header = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "lifting": kind,
            "n_lift": 0 if self.lifting_ is None else self.lifting_.n_lift,
            "n_lifted": self.n_lifted_,
            "include_state": self.include_state,
            "nx": self.nx_,
            "nu": self.nu_,
            "ny": self.ny_,
            "output_is_state": self.output_is_state_,
            "params": self.get_params(),
            "fit_time_s": self.fit_time_s_,
            "stopped_early": self.stopped_early_,
            "epochs_run": self.epochs_run_,
            "user": dict(metadata) if metadata is not None else {},
        }
        arrays: dict[str, np.ndarray] = {name: getattr(self, f"{name}_") for name in _MATRICES}
        arrays["history"] = np.array(self.history_, dtype=float).reshape(-1, 2)
        arrays["x_min"] = np.asarray(self.x_min_, dtype=float)
        arrays["x_max"] = np.asarray(self.x_max_, dtype=float)
        if self.lifting_ is not None:
            for key, value in self.lifting_.to_arrays().items():
                arrays[f"lifting.{key}"] = value
        arrays["metadata"] = np.array(json.dumps(header, default=json_default))
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as handle:
                np.savez(handle, allow_pickle=False, **arrays)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    @classmethod
    def load(cls, path: str | Path) -> KoopmanModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        InputFileError
            Missing or unreadable file, not an ``.npz`` archive, wrong format name or version, missing
            array, or arrays whose shapes do not fit together.
        """
        path = Path(path)
        if not path.is_file():
            raise InputFileError(path, "file not found")
        arrays = _read_npz(path)

        if "metadata" not in arrays:
            raise InputFileError(path, "no metadata entry: not an rkmpc Koopman model", field="metadata")
        try:
            header = json.loads(str(arrays["metadata"].reshape(())))
        except (ValueError, TypeError) as exc:
            raise InputFileError(path, f"metadata is not valid JSON ({exc})", field="metadata") from None
        if not isinstance(header, dict):
            raise InputFileError(path, "metadata is not a JSON object", field="metadata")
        if header.get("format") != FORMAT_NAME:
            raise InputFileError(
                path, f"format is {header.get('format')!r}, expected {FORMAT_NAME!r}", field="metadata.format"
            )
        version = header.get("format_version")
        if version not in READABLE_VERSIONS:
            readable = ", ".join(map(str, READABLE_VERSIONS))
            raise InputFileError(
                path,
                f"unsupported format version {version!r} (readable: {readable})",
                field="metadata.format_version",
            )
        sizes: dict[str, int] = {}
        for key in ("nx", "nu", "ny", "n_lifted", "n_lift"):
            value = header.get(key)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                problem = f"{key} must be a non-negative integer, got {value!r}"
                raise InputFileError(path, problem, field=f"metadata.{key}")
            sizes[key] = value
        kind = header.get("lifting")
        if kind not in LIFTING_KINDS:
            raise InputFileError(path, f"unknown lifting kind {kind!r}", field="metadata.lifting")
        params = header.get("params")
        if not isinstance(params, dict):
            raise InputFileError(path, "params must be a JSON object", field="metadata.params")
        params = dict(params)
        if isinstance(params.get("hidden"), list):
            params["hidden"] = tuple(params["hidden"])
        try:
            model = cls(**params)
            model._validate_params()
        except (TypeError, ParameterError) as exc:
            raise InputFileError(path, f"bad training parameters: {exc}", field="metadata.params") from None
        if model.lifting != kind:
            problem = f"lifting {kind!r} but params say {model.lifting!r}"
            raise InputFileError(path, problem, field="metadata.lifting")
        if header.get("include_state") != model.include_state:
            raise InputFileError(path, "include_state disagrees with params", field="metadata.include_state")

        # Matrices: present, 2-D, finite, shapes consistent.
        mats: dict[str, np.ndarray] = {}
        for name in _MATRICES:
            if name not in arrays:
                raise InputFileError(path, f"missing array {name!r}", field=name)
            value = arrays[name]
            if value.ndim != 2 or not np.issubdtype(value.dtype, np.number):
                problem = f"{name} must be a 2-D numeric array, got shape {value.shape}"
                raise InputFileError(path, problem, field=name)
            if not np.all(np.isfinite(value)):
                raise InputFileError(path, f"{name} contains NaN or infinite values", field=name)
            mats[name] = value.astype(float)
        nz, nx, nu, ny = sizes["n_lifted"], sizes["nx"], sizes["nu"], sizes["ny"]
        expected = {"A": (nz, nz), "B": (nz, nu), "C": (ny, nz), "D": (ny, nu), "Cx": (nx, nz)}
        if mats["A"].shape[0] != mats["A"].shape[1]:
            raise InputFileError(path, f"A must be square, got {mats['A'].shape}", field="A")
        for name, shape in expected.items():
            if mats[name].shape != shape:
                raise InputFileError(
                    path,
                    f"{name} has shape {mats[name].shape}, expected {shape} (nz={nz}, nx={nx}, "
                    f"nu={nu}, ny={ny})",
                    field=name,
                )

        lifting: Lifting | None = None
        if kind != "none":
            prefix = "lifting."
            sub = {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}
            factory = MLPLifting if kind == "mlp" else RBFLifting
            try:
                lifting = factory.from_arrays(sub)
            except KeyError as exc:
                key = str(exc.args[0]) if exc.args else "?"
                raise InputFileError(path, f"missing lifting array {key!r}", field=prefix + key) from None
            except (ParameterError, ValueError, TypeError, IndexError) as exc:
                raise InputFileError(path, f"invalid lifting arrays: {exc}", field="lifting") from None
            if lifting.nx != nx or lifting.n_lift != sizes["n_lift"]:
                raise InputFileError(
                    path,
                    f"lifting maps {lifting.nx} -> {lifting.n_lift}, metadata says {nx} -> {sizes['n_lift']}",
                    field="lifting",
                )
        n_state = nx if model.include_state else 0
        n_psi = 0 if lifting is None else lifting.n_lift
        if nz != n_state + n_psi:
            raise InputFileError(
                path,
                f"n_lifted={nz}, but state block ({n_state}) + lifting ({n_psi}) = {n_state + n_psi}",
                field="metadata.n_lifted",
            )

        if version == 1:
            x_min, x_max = np.full(nx, -np.inf), np.full(nx, np.inf)
        else:
            x_min, x_max = (_state_range(path, arrays, key, nx) for key in ("x_min", "x_max"))
            if np.any(x_min > x_max):
                raise InputFileError(path, "x_min exceeds x_max for some feature", field="x_min")

        model.lifting_ = lifting
        model.x_min_, model.x_max_ = x_min, x_max
        model.A_, model.B_, model.C_, model.D_, model.Cx_ = (mats[k] for k in _MATRICES)
        model.n_lifted_, model.nx_, model.nu_, model.ny_ = nz, nx, nu, ny
        model.output_is_state_ = bool(header.get("output_is_state", False))
        history = arrays.get("history", np.zeros((0, 2)))
        model.history_ = [(int(e), float(v)) for e, v in np.asarray(history).reshape(-1, 2)]
        model.fit_time_s_ = float(header.get("fit_time_s", float("nan")))
        model.stopped_early_ = bool(header.get("stopped_early", False))
        model.epochs_run_ = int(header.get("epochs_run", 0))
        model.metadata_ = dict(header.get("user") or {})
        return model


def _state_range(path: Path, arrays: dict[str, np.ndarray], key: str, nx: int) -> np.ndarray:
    """The ``x_min`` or ``x_max`` array of a saved model: present, shape (nx,), finite."""
    if key not in arrays:
        raise InputFileError(path, f"missing array {key!r}", field=key)
    value = arrays[key]
    if value.shape != (nx,) or not np.issubdtype(value.dtype, np.number):
        problem = f"{key} must be a numeric array of shape ({nx},), got {value.shape}"
        raise InputFileError(path, problem, field=key)
    if not np.all(np.isfinite(value)):
        raise InputFileError(path, f"{key} contains NaN or infinite values", field=key)
    return value.astype(float)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` file, or InputFileError when it is not a readable archive."""
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise InputFileError(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise InputFileError(path, "not an .npz archive (a single .npy array)")
    try:
        with loaded:
            return {key: loaded[key] for key in loaded.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise InputFileError(path, f"damaged .npz archive ({type(exc).__name__}: {exc})") from None
