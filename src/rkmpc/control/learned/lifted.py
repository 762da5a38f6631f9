"""What the Koopman MPCs share: the model they need, its condensed prediction, the local frame.

:class:`LiftedModel` is what a learned controller asks of a model (a fitted
:class:`rkmpc.learning.koopman.model.KoopmanModel`); :func:`lifted_prediction`
stacks its outputs over a horizon once; :func:`reference_in_local_frame` puts
the reference poses into the car's own frame, where a model trained on
local-frame windows predicts.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

import numpy as np

from rkmpc.core.angles import branch_shift
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.learning.features import FeatureMap
from rkmpc.learning.recipes import recipe_for

if TYPE_CHECKING:
    from rkmpc.track.reference import ReferenceHorizon

__all__ = ["LiftedModel", "lifted_prediction", "recipe_state", "reference_in_local_frame"]


class LiftedModel(Protocol):
    """What the Koopman MPCs need of a learned model (a fitted ``KoopmanModel``)."""

    A_: np.ndarray
    B_: np.ndarray
    C_: np.ndarray
    D_: np.ndarray

    def lift(self, X: np.ndarray) -> np.ndarray: ...


def recipe_state(controller: str) -> FeatureMap:
    """The state features of a learned controller's recipe: the map its model was trained on."""
    recipe = recipe_for(controller)
    if recipe is None or recipe.state is None:
        raise ParameterError(f"no Koopman recipe for the controller {controller!r}")
    return recipe.state


def reference_in_local_frame(ref: ReferenceHorizon, observation: Observation) -> np.ndarray:
    """Reference poses ``k = 1..N`` in the car's frame (origin at the car, heading 0), shape (N, 3).

    Headings are continuous along the horizon, on the branch where the first one lies within pi of 0.
    """
    c, s = math.cos(observation.yaw), math.sin(observation.yaw)
    dx, dy = ref.x[1:] - observation.x, ref.y[1:] - observation.y
    local = np.empty((dx.shape[0], 3))
    np.subtract(ref.theta[1:], observation.yaw, out=local[:, 2])
    local[:, 2] -= branch_shift(float(local[0, 2]))
    local[:, 0] = c * dx + s * dy
    local[:, 1] = -s * dx + c * dy
    return local


def lifted_prediction(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray | None, horizon: int, *, first: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Stacked outputs of ``z+ = A z + B u``, ``y = C z + D u`` over a horizon.

    Returns ``(Mz, Mu)`` with ``[y_first; ...; y_{first+N-1}] = Mz z_0 + Mu [u_0; ...; u_{N-1}]``,
    where ``y_k`` uses ``u_k`` through ``D`` only when ``k < N``.

    Parameters
    ----------
    A : numpy.ndarray
        Lifted state matrix, shape (nz, nz).
    B : numpy.ndarray
        Input matrix, shape (nz, nu).
    C : numpy.ndarray
        Output matrix, shape (ny, nz).
    D : numpy.ndarray or None
        Feed-through matrix, shape (ny, nu), or None for none.
    horizon : int
        N, the number of inputs.
    first : int
        Index of the first output: 0 for ``y_0..y_{N-1}`` (outputs that depend on
        the input applied at the same step), 1 for ``y_1..y_N`` (predicted states).

    Returns
    -------
    Mz : numpy.ndarray
        Shape (N*ny, nz).
    Mu : numpy.ndarray
        Shape (N*ny, N*nu).
    """
    nz, nu = B.shape
    ny = C.shape[0]
    n = horizon
    # Powers A^k, k = 0..N.
    powers = [np.eye(nz)]
    for _ in range(n):
        powers.append(A @ powers[-1])
    Mz = np.empty((n, ny, nz))
    Mu = np.zeros((n, ny, n, nu))
    CAB = [C @ powers[k] @ B for k in range(n + 1)]
    for row in range(n):
        k = row + first
        Mz[row] = C @ powers[k]
        for j in range(min(k, n)):
            Mu[row, :, j, :] = CAB[k - 1 - j]
        if D is not None and k < n:
            Mu[row, :, k, :] += D
    return Mz.reshape(n * ny, nz), Mu.reshape(n * ny, n * nu)
