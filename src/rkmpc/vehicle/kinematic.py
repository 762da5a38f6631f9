"""The kinematic bicycle model of the paper (Sec. III-A, Eq. 1-3).

State ``[x, y, theta]`` (m, m, rad), input ``[v, delta]`` (m/s, rad):

.. math::

    \\dot x = v \\cos\\theta, \\quad \\dot y = v \\sin\\theta, \\quad
    \\dot\\theta = \\frac{v}{L} \\tan\\delta

with wheelbase ``L`` (m). :func:`linearize_discrete` gives the paper's
discrete deviation model ``xi(k+1) = A(k) xi(k) + B(k) (u(k) - u_r(k))`` with
``xi = [x - x_r, y - y_r, theta - theta_r]``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from rkmpc.core.errors import ParameterError

#: Names of the kinematic state components, in order.
KINEMATIC_STATE_NAMES: tuple[str, ...] = ("x", "y", "theta")
#: Names of the kinematic input components, in order.
KINEMATIC_INPUT_NAMES: tuple[str, ...] = ("v", "delta")


def _positive_float(given: float, name: str) -> float:
    value = float(given)
    if not (math.isfinite(value) and value > 0.0):
        raise ParameterError(f"{name} must be finite and > 0, got {given!r}")
    return value


def _as_vector(value: ArrayLike, size: int, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != (size,):
        raise ValueError(f"{name} must have shape ({size},), got {array.shape}")
    return array


def kinematic_rhs(state: ArrayLike, u: ArrayLike, wheelbase: float) -> np.ndarray:
    """Time derivative of the kinematic bicycle state (paper Eq. 1).

    Parameters
    ----------
    state : array_like, shape (3,)
        ``[x, y, theta]``: position (m) and heading (rad).
    u : array_like, shape (2,)
        ``[v, delta]``: speed (m/s) and front wheel angle (rad).
    wheelbase : float
        Wheelbase ``L`` (m).

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``[xdot, ydot, thetadot]`` (m/s, m/s, rad/s).
    """
    length = _positive_float(wheelbase, "wheelbase")
    x = _as_vector(state, 3, "state")
    inp = _as_vector(u, 2, "u")
    speed, steer = float(inp[0]), float(inp[1])
    theta = float(x[2])
    return np.array([speed * math.cos(theta), speed * math.sin(theta), speed * math.tan(steer) / length])


def kinematic_step(state: ArrayLike, u: ArrayLike, wheelbase: float, dt: float) -> np.ndarray:
    """Advance the kinematic bicycle by ``dt`` holding the input constant.

    The integration is exact: with constant speed and wheel angle the car
    drives along a circular arc of curvature ``tan(delta) / L`` (or a straight
    line when ``delta`` is zero).

    Parameters
    ----------
    state : array_like, shape (3,)
        ``[x, y, theta]`` (m, m, rad).
    u : array_like, shape (2,)
        ``[v, delta]`` (m/s, rad).
    wheelbase : float
        Wheelbase ``L`` (m).
    dt : float
        Step length (s), > 0.

    Returns
    -------
    numpy.ndarray, shape (3,)
        The state after ``dt``.
    """
    length = _positive_float(wheelbase, "wheelbase")
    step = _positive_float(dt, "dt")
    x = _as_vector(state, 3, "state")
    inp = _as_vector(u, 2, "u")
    speed, steer = float(inp[0]), float(inp[1])
    theta = float(x[2])
    distance = speed * step
    dtheta = distance * math.tan(steer) / length
    # sin(d/2)/(d/2) is the chord factor of the arc; use its series near zero.
    half = 0.5 * dtheta
    chord = 1.0 - half * half / 6.0 if abs(half) < 1e-4 else math.sin(half) / half
    mid = theta + half
    return np.array(
        [
            float(x[0]) + distance * chord * math.cos(mid),
            float(x[1]) + distance * chord * math.sin(mid),
            theta + dtheta,
        ]
    )


def linearize_discrete(
    theta_r: ArrayLike,
    v_r: ArrayLike,
    delta_r: ArrayLike,
    wheelbase: float,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Discrete linearisation of the kinematic model along a reference (paper Eq. 2-3).

    The deviation model is ``xi(k+1) = A(k) xi(k) + B(k) (u(k) - u_r(k))``
    with ``xi = [x - x_r, y - y_r, theta - theta_r]`` and input order
    ``[v, delta]``; it is the Jacobian of the forward-Euler map
    ``state + dt * f(state, u)`` at the reference.

    Parameters
    ----------
    theta_r : array_like, shape (n,) or scalar
        Reference heading (rad).
    v_r : array_like, shape (n,) or scalar
        Reference speed (m/s).
    delta_r : array_like, shape (n,) or scalar
        Reference front wheel angle (rad).
    wheelbase : float
        Wheelbase ``L`` (m).
    dt : float
        Sampling time ``T`` (s).

    Returns
    -------
    A : numpy.ndarray, shape (n, 3, 3), or (3, 3) for scalar inputs
        State transition matrices.
    B : numpy.ndarray, shape (n, 3, 2), or (3, 2) for scalar inputs
        Input matrices.
    """
    length = _positive_float(wheelbase, "wheelbase")
    step = _positive_float(dt, "dt")
    theta, speed, steer = np.broadcast_arrays(
        np.asarray(theta_r, dtype=float), np.asarray(v_r, dtype=float), np.asarray(delta_r, dtype=float)
    )
    if theta.ndim > 1:
        raise ValueError(f"reference arrays must be scalars or 1-D, got shape {theta.shape}")
    scalar = theta.ndim == 0
    theta, speed, steer = np.atleast_1d(theta), np.atleast_1d(speed), np.atleast_1d(steer)
    n = theta.shape[0]
    sin_t, cos_t = np.sin(theta), np.cos(theta)

    a_mat = np.zeros((n, 3, 3))
    a_mat[:, 0, 0] = 1.0
    a_mat[:, 1, 1] = 1.0
    a_mat[:, 2, 2] = 1.0
    a_mat[:, 0, 2] = -speed * sin_t * step
    a_mat[:, 1, 2] = speed * cos_t * step

    b_mat = np.zeros((n, 3, 2))
    b_mat[:, 0, 0] = cos_t * step
    b_mat[:, 1, 0] = sin_t * step
    b_mat[:, 2, 0] = np.tan(steer) * step / length
    b_mat[:, 2, 1] = speed * step / (length * np.cos(steer) ** 2)

    if scalar:
        return a_mat[0], b_mat[0]
    return a_mat, b_mat
