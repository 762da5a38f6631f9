"""Lateral tyre forces: the simplified Pacejka magic formula, and tyre models a plant composes."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from rkmpc.core.validation import require_positive
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


#: ``force(alpha, fz, mu)``: lateral force (N) of one axle at slip angle ``alpha`` (rad),
#: vertical load ``fz`` (N) and friction coefficient ``mu`` (-).
LateralForce = Callable[[float, float, float], float]


class TyreModel(ABC):
    """Description of an axle's lateral tyre force; :meth:`build` returns the force law."""

    @abstractmethod
    def build(self) -> LateralForce:
        """The scalar force law ``force(alpha, fz, mu)`` (N)."""


@dataclass(frozen=True)
class PacejkaTyre(TyreModel):
    """The simplified magic formula (:func:`pacejka_lateral_force`): it saturates at ``mu Fz D``.

    Parameters
    ----------
    params : PacejkaParams
        Magic-formula coefficients.
    """

    params: PacejkaParams

    def build(self) -> LateralForce:
        b, c, d, e = self.params.B, self.params.C, self.params.D, self.params.E
        sin, atan = math.sin, math.atan

        def force(alpha: float, fz: float, mu: float) -> float:
            ba = b * alpha
            return mu * fz * d * sin(c * atan(ba - e * (ba - atan(ba))))

        return force


@dataclass(frozen=True)
class LinearTyre(TyreModel):
    """Linear in slip and load, with no saturation: ``Fy = mu C Fz alpha``.

    The tyre of the F1TENTH gym's single-track model (CommonRoad's ``C_S``
    cornering-stiffness coefficients): it never runs out of grip, so a car
    built with it turns as hard as it is asked to.

    Parameters
    ----------
    stiffness_per_load : float
        ``C`` (1/rad): cornering stiffness per unit of ``mu Fz``, > 0.
    """

    stiffness_per_load: float

    def __post_init__(self) -> None:
        require_positive(self, "stiffness_per_load")

    def build(self) -> LateralForce:
        c = self.stiffness_per_load

        def force(alpha: float, fz: float, mu: float) -> float:
            return mu * c * fz * alpha

        return force
