"""Physical identification from on-track data: servo lag and understeer gradient.

This is what a skeptical engineer identifies from the same laps before reaching
for a neural network: the steering servo's first-order time constant and the
understeer gradient of the car, both by linear least squares.

The understeer model is defined once, here, and used both by the fit and by the
controller that drives with it (``lmpc-id``): the path curvature a wheel angle
``delta`` produces at speed ``v`` is ``tan(delta) / (L + K v^2)``
(:func:`effective_wheelbase`), so steady cornering on curvature ``kappa`` needs
``delta = atan((L + K v^2) kappa)`` (:func:`steady_state_steer`), and on data the
part of ``tan(delta)`` beyond the kinematic ``L r / v`` is ``K v r``
(:func:`understeer_excess`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS

#: Columns of the observation arrays.
_SPEED, _YAW_RATE, _STEER = (OBSERVATION_FIELDS.index(n) for n in ("speed", "yaw_rate", "steer_angle"))


class _Transitions(Protocol):
    @property
    def obs(self) -> np.ndarray: ...
    @property
    def command(self) -> np.ndarray: ...
    @property
    def next_obs(self) -> np.ndarray: ...
    @property
    def dt(self) -> float: ...


@dataclass(frozen=True)
class IdentifiedModel:
    """Servo lag and understeer identified from data.

    Parameters
    ----------
    servo_time_constant : float
        First-order time constant of the steering servo (s).
    understeer_gradient : float
        ``K`` (s^2/m, that is m per (m/s)^2): the effective wheelbase grows as
        ``L + K v^2``, so steady cornering needs ``tan(delta) = (L + K v^2) kappa``
        (:func:`steady_state_steer`); for small angles, the extra wheel angle per unit
        lateral acceleration (rad per m/s^2).
    servo_fit_r2, understeer_fit_r2 : float
        Coefficients of determination of the two fits.
    n_samples : int
        Transitions used.
    """

    servo_time_constant: float
    understeer_gradient: float
    servo_fit_r2: float
    understeer_fit_r2: float
    n_samples: int

    def __post_init__(self) -> None:
        if not (math.isfinite(self.servo_time_constant) and self.servo_time_constant > 0):
            raise ParameterError(
                f"IdentifiedModel.servo_time_constant must be > 0, got {self.servo_time_constant!r}"
            )
        if not math.isfinite(self.understeer_gradient):
            raise ParameterError("IdentifiedModel.understeer_gradient must be finite")


def identify(data: _Transitions, wheelbase: float, *, min_speed: float = 1.0) -> IdentifiedModel:
    """Identify the servo time constant and the understeer gradient.

    Parameters
    ----------
    data : TransitionDataset
        Transitions with measured wheel angle and yaw rate (observation
        columns ``steer_angle`` and ``yaw_rate``).
    wheelbase : float
        Wheelbase L (m).
    min_speed : float
        Transitions slower than this (m/s) are left out of the understeer fit.

    Returns
    -------
    IdentifiedModel

    Notes
    -----
    Servo: ``delta_{k+1} - delta_k = b (delta_cmd,k - delta_k)`` by least
    squares, then ``tau = -T / ln(1 - b)`` (exact for a first-order lag held
    over the period T). Understeer: ``tan(delta_k) - L r_k / v_k = K v_k r_k``
    (:func:`understeer_excess` against lateral acceleration), the model
    :func:`steady_state_steer` drives with.
    """
    obs, nxt, cmd = np.asarray(data.obs), np.asarray(data.next_obs), np.asarray(data.command)
    steer, steer_next = obs[:, _STEER], nxt[:, _STEER]
    speed, yaw_rate = obs[:, _SPEED], obs[:, _YAW_RATE]
    ok = np.isfinite(steer) & np.isfinite(steer_next) & np.isfinite(cmd[:, 1])
    if ok.sum() < 20:
        raise ParameterError("identify: needs at least 20 transitions with a measured wheel angle")
    gap = cmd[ok, 1] - steer[ok]
    change = steer_next[ok] - steer[ok]
    b = float(gap @ change / max(gap @ gap, 1e-12))
    if not 0.0 < b < 1.0:
        raise ParameterError(f"identify: servo fit gives a step gain {b:.3f} outside (0, 1)")
    tau = -data.dt / math.log(1.0 - b)
    servo_r2 = _r2(change, b * gap)

    ok_u = ok & np.isfinite(yaw_rate) & (speed > min_speed)
    if ok_u.sum() < 20:
        raise ParameterError("identify: needs at least 20 transitions faster than min_speed with a yaw rate")
    v, r, d = speed[ok_u], yaw_rate[ok_u], steer[ok_u]
    excess = understeer_excess(d, v, r, wheelbase)
    a_lat = v * r
    k = float(a_lat @ excess / max(a_lat @ a_lat, 1e-12))
    return IdentifiedModel(
        servo_time_constant=tau,
        understeer_gradient=k,
        servo_fit_r2=servo_r2,
        understeer_fit_r2=_r2(excess, k * a_lat),
        n_samples=int(ok.sum()),
    )


def effective_wheelbase(wheelbase: float, gradient: float, speed: np.ndarray) -> np.ndarray:
    """``L + K v^2`` (m): the wheelbase with which a kinematic model corners like the car at ``v`` (m/s)."""
    return wheelbase + gradient * speed * speed


def steady_state_steer(
    curvature: np.ndarray, speed: np.ndarray, wheelbase: float, gradient: float
) -> np.ndarray:
    """Wheel angle (rad) holding curvature ``kappa`` (1/m) at ``v`` (m/s): ``atan((L + K v^2) kappa)``."""
    return np.arctan(effective_wheelbase(wheelbase, gradient, speed) * curvature)


def understeer_excess(
    steer: np.ndarray, speed: np.ndarray, yaw_rate: np.ndarray, wheelbase: float
) -> np.ndarray:
    """``tan(delta) - L r / v``: the tangent of the wheel angle beyond the kinematic one (``K v r``)."""
    return np.tan(steer) - wheelbase * yaw_rate / speed


def _r2(y: np.ndarray, fit: np.ndarray) -> float:
    ss = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - fit) ** 2)) / ss if ss > 0 else 1.0
