"""Simplified Pacejka magic-formula lateral tyre force."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from rkmpc.vehicle.params import PacejkaParams


def pacejka_lateral_force(alpha: float, fz: float, params: PacejkaParams, mu: float) -> float:
    """Lateral force of one axle from the simplified magic formula (scalar, fast).

    ``Fy = mu * Fz * D * sin(C * atan(B*a - E*(B*a - atan(B*a))))``.

    Parameters
    ----------
    alpha : float
        Slip angle (rad); positive slip gives positive (leftward) force.
    fz : float
        Vertical load on the axle (N).
    params : PacejkaParams
        Magic-formula coefficients.
    mu : float
        Friction coefficient (-).

    Returns
    -------
    float
        Lateral force (N).
    """
    ba = params.B * alpha
    return mu * fz * params.D * math.sin(params.C * math.atan(ba - params.E * (ba - math.atan(ba))))


def pacejka_lateral_force_array(
    alpha: ArrayLike, fz: ArrayLike, params: PacejkaParams, mu: ArrayLike
) -> np.ndarray:
    """Vectorised :func:`pacejka_lateral_force`.

    Parameters
    ----------
    alpha : array_like, shape (n,)
        Slip angles (rad).
    fz : array_like, shape (n,) or scalar
        Vertical loads (N).
    params : PacejkaParams
        Magic-formula coefficients.
    mu : array_like, shape (n,) or scalar
        Friction coefficients (-).

    Returns
    -------
    numpy.ndarray, shape (n,)
        Lateral forces (N), broadcast over the inputs.
    """
    ba = params.B * np.asarray(alpha, dtype=float)
    shape = np.sin(params.C * np.arctan(ba - params.E * (ba - np.arctan(ba))))
    return np.asarray(mu, dtype=float) * np.asarray(fz, dtype=float) * params.D * shape
