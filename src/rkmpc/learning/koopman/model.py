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

The dictionary ``psi`` is a lifting object composed into the model, as in pykoop
(:mod:`rkmpc.learning.koopman.lifting`):

* :class:`~rkmpc.learning.koopman.lifting.MLPLifting`: a two-hidden-layer ReLU network trained with the
  paper's pseudo-Huber loss on the one-step lifted residual, with ``A, B`` recomputed in closed form on
  each batch (:mod:`rkmpc.learning.koopman.training`);
* :class:`~rkmpc.learning.koopman.lifting.RBFLifting`: a fixed radial-basis dictionary (plain EDMD);
* ``None``: no dictionary, ``z = x`` (plain DMD with inputs; a linear baseline).

The network and the least-squares fit only know the states they were trained on. Outside that range
their output is an extrapolation, and on nearly constant data a wild one: on the IMS oval the car
drives at its top speed almost everywhere, the speed feature of the residual model spans 1e-5 m/s,
and a speed 1 cm/s below it made the model predict a 0.46 m/s, 0.009 rad residual. So the model
records the range of its training states (``x_min_``, ``x_max_``) and, with ``clip_inputs`` (the
default), :meth:`KoopmanModel.lift` clips a state into that range before lifting it: outside the
data the model answers as at the nearest edge of what it has seen.

A fitted model is stored as one ``.npz`` file (:meth:`KoopmanModel.save` / :meth:`KoopmanModel.load`,
format in :mod:`rkmpc.learning.koopman.io`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.learning.koopman import io as model_io
from rkmpc.learning.koopman.checks import checked_data, finite_array
from rkmpc.learning.koopman.edmd import fit_dynamics, fit_output
from rkmpc.learning.koopman.lifting import Lifting, MLPLifting, RBFLifting, clone

__all__ = ["KoopmanModel"]


class KoopmanModel:
    """Lifted linear model ``z+ = A z + B u``, ``y = C z + D u`` with a composed lifting.

    Parameters
    ----------
    lifting : MLPLifting, RBFLifting or None
        The dictionary ``psi`` (unfitted settings; :meth:`fit` fits a copy), or None for no
        dictionary (``z = x``).
    include_state : bool
        Whether ``x`` itself is the first block of ``z`` (required without a lifting).
    ridge : float
        Tikhonov weight of the least-squares fits, dimensionless (see
        :func:`rkmpc.learning.koopman.edmd.ridge_lstsq`).
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
        The fitted dictionary.
    n_lifted_ : int
        ``nz``.
    nx_, nu_, ny_ : int
        Sizes of state, input and output.
    output_is_state_ : bool
        True when no ``Y`` was given (``y = x``).
    history_ : list of (int, float)
        ``(epoch, mean training loss)`` of a trained network; epoch 0 is the untrained one.
    epochs_run_ : int
        Training epochs completed (0 without a network).
    fit_time_s_ : float
        Wall-clock duration of :meth:`fit` (s), for reports only.
    metadata_ : dict
        Caller metadata read by :meth:`load` (empty after :meth:`fit`).
    """

    def __init__(
        self,
        lifting: Lifting | None,
        *,
        include_state: bool = True,
        ridge: float = 1e-6,
        clip_inputs: bool = True,
    ) -> None:
        self.lifting = lifting
        self.include_state = include_state
        self.ridge = ridge
        self.clip_inputs = clip_inputs

    def get_params(self) -> dict[str, Any]:
        """Settings as plain JSON types: the lifting's (or None) and the model's own."""
        return {
            "lifting": None if self.lifting is None else self.lifting.get_params(),
            "include_state": self.include_state,
            "ridge": self.ridge,
            "clip_inputs": self.clip_inputs,
        }

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> KoopmanModel:
        """An unfitted model from :meth:`get_params` output (ParameterError when bad)."""
        return model_io.model_from_params(cls, params)

    def __repr__(self) -> str:
        return (
            f"KoopmanModel({self.lifting!r}, include_state={self.include_state!r}, ridge={self.ridge!r}, "
            f"clip_inputs={self.clip_inputs!r})"
        )

    def validate(self) -> None:
        """Raise :class:`ParameterError` for bad settings."""
        if self.lifting is not None and not isinstance(self.lifting, (MLPLifting, RBFLifting)):
            raise ParameterError(
                f"lifting must be an MLPLifting, an RBFLifting or None, got {self.lifting!r}"
            )
        for flag in ("include_state", "clip_inputs"):
            if not isinstance(getattr(self, flag), bool):
                raise ParameterError(f"{flag} must be a bool, got {getattr(self, flag)!r}")
        if self.lifting is None and not self.include_state:
            raise ParameterError("a model without a lifting needs include_state=True (otherwise z is empty)")
        ridge = self.ridge
        if isinstance(ridge, bool) or not isinstance(ridge, (int, float, np.floating)) or not ridge >= 0:
            raise ParameterError(f"ridge must be a finite number >= 0, got {ridge!r}")
        if not np.isfinite(ridge):
            raise ParameterError(f"ridge must be a finite number >= 0, got {ridge!r}")
        if self.lifting is not None:
            self.lifting.validate()

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
        """Learn the lifting and the matrices from one-step data.

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
            a network's loss. When omitted, windows are taken from runs of consecutive samples in
            ``X, X_next`` (``X_next[k] == X[k+1]``), if any.
        on_epoch : callable, optional
            Progress callback ``on_epoch(epoch, mean_loss)`` (network only).

        Returns
        -------
        self
        """
        self.validate()
        X, U, X_next, Y, windows = checked_data(X, U, X_next, Y, windows)
        start = time.perf_counter()
        self.metadata_: dict[str, Any] = {}
        lifting = clone(self.lifting)
        if lifting is not None:
            lifting.fit(
                X,
                U,
                X_next,
                Y=Y,
                windows=windows,
                include_state=self.include_state,
                ridge=float(self.ridge),
                on_epoch=on_epoch,
            )
        self.lifting_ = lifting
        self.history_: list[tuple[int, float]] = list(getattr(lifting, "history_", []))
        self.epochs_run_ = int(getattr(lifting, "epochs_run_", 0))
        nx, nu = X.shape[1], U.shape[1]
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
        """Outputs ``y_0 .. y_{H-1}``, shape (H, ny), along inputs ``U`` (H, nu) from state ``x0`` (nx,)."""
        self._check_fitted()
        U = self._check_inputs(U, 2, "U")
        Zs = self._rollout(self.lift(np.asarray(x0, dtype=float))[None, :], U[None])[0]
        return Zs[:-1] @ self.C_.T + U @ self.D_.T

    def predict_states(self, x0: np.ndarray, U: np.ndarray) -> np.ndarray:
        """State features ``x_0 .. x_H``, shape (H+1, nx), read from the lifted state through ``Cx_``.

        Row 0 is ``x0`` itself when ``include_state``; ``U`` has shape (H, nu).
        """
        self._check_fitted()
        U = self._check_inputs(U, 2, "U")
        Zs = self._rollout(self.lift(np.asarray(x0, dtype=float))[None, :], U[None])[0]
        return Zs @ self.Cx_.T

    def multi_step_error(self, Xw: np.ndarray, Uw: np.ndarray, Yw: np.ndarray | None = None) -> np.ndarray:
        """Mean prediction-error norm per horizon step on held-out sequences (open loop from the first state).

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
        Xw = finite_array(Xw, "Xw", 3)
        Uw = self._check_inputs(Uw, 3, "Uw")
        if Xw.shape[0] != Uw.shape[0] or Xw.shape[1] != Uw.shape[1] + 1 or Xw.shape[2] != self.nx_:
            raise ParameterError(f"Xw {Xw.shape} and Uw {Uw.shape} must be (M, H+1, {self.nx_}), (M, H, nu)")
        Zs = self._rollout(self.lift(Xw[:, 0]), Uw)
        if Yw is None:
            err = Zs[:, 1:] @ self.Cx_.T - Xw[:, 1:]
        else:
            Yw = finite_array(Yw, "Yw", 3)
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
        model_io.write_model(path, self, metadata)

    @classmethod
    def load(cls, path: str | Path) -> KoopmanModel:
        """Read a model written by :meth:`save` (any readable format version).

        Raises
        ------
        InputFileError
            Missing or unreadable file, not an ``.npz`` archive, wrong format name or version, missing
            array, or arrays whose shapes do not fit together.
        """
        stored = model_io.read_model(path, cls)
        model = stored.model
        model.lifting_ = stored.lifting
        model.x_min_, model.x_max_ = stored.x_min, stored.x_max
        model.A_, model.B_, model.C_, model.D_, model.Cx_ = stored.matrices
        model.n_lifted_, model.nx_, model.nu_, model.ny_ = stored.sizes
        model.output_is_state_ = stored.output_is_state
        model.history_ = stored.history
        model.fit_time_s_ = stored.fit_time_s
        model.epochs_run_ = stored.epochs_run
        model.metadata_ = stored.metadata
        return model
