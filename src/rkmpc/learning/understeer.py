"""The understeer model: defined once, fitted by identification, driven with by ``lmpc-id``.

The path curvature a wheel angle ``delta`` produces at speed ``v`` is
``tan(delta) / (L + K v^2)`` (:func:`effective_wheelbase`), so the yaw rate is
``r = v tan(delta) / (L + K v^2)`` (:func:`yaw_rate_of`), steady cornering on
curvature ``kappa`` needs ``delta = atan((L + K v^2) kappa)``
(:func:`steady_state_steer`), and on data the part of ``tan(delta)`` beyond the
kinematic ``L r / v`` is ``K v r`` (:func:`understeer_excess`).

:func:`fit_gradients` estimates ``K`` for many wheel-angle histories and many
sample weights at once: the least squares of ``(L + K v^2) r - v tan(delta)``,
linear in ``K`` (the output error ``r - v tan(delta) / (L + K v^2)`` is that
divided by the effective wheelbase), held inside the plausible range of
:func:`gradient_bounds`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "UNDERSTEER_RANGE",
    "effective_wheelbase",
    "fit_gradients",
    "gradient_bounds",
    "steady_state_steer",
    "understeer_excess",
    "yaw_rate_of",
]

#: Plausible understeer gradients K (rad of extra wheel angle per m/s^2 of lateral acceleration,
#: that is s^2/m), about -11 to +56 deg/g: a factor of ten beyond what road cars (+1 to +4 deg/g)
#: and model cars show, either way. K is a wheel angle per lateral acceleration, so the range
#: does not depend on the size of the car. Besides, the car cannot have been beyond its critical
#: speed ``sqrt(-L / K)`` in its own data (:func:`gradient_bounds`).
UNDERSTEER_RANGE = (-0.02, 0.1)


def gradient_bounds(wheelbase: float, top_speed: float) -> tuple[float, float]:
    """Plausible K (s^2/m) for a car that drove up to ``top_speed`` (m/s): :data:`UNDERSTEER_RANGE`, and
    ``K >= -L / (2 v_max^2)``, half-way to the critical speed."""
    lower = max(UNDERSTEER_RANGE[0], -0.5 * wheelbase / max(top_speed, 1e-6) ** 2)
    return lower, UNDERSTEER_RANGE[1]


def effective_wheelbase(wheelbase: float, gradient: float | np.ndarray, speed: np.ndarray) -> np.ndarray:
    """``L + K v^2`` (m): the wheelbase with which a kinematic model corners like the car at ``v`` (m/s)."""
    return wheelbase + gradient * speed * speed


def yaw_rate_of(
    tan_wheel: np.ndarray, speed: np.ndarray, wheelbase: float, gradient: float | np.ndarray
) -> np.ndarray:
    """Yaw rate (rad/s) ``v tan(delta) / (L + K v^2)`` of a car at ``v`` (m/s) with ``tan(delta)``."""
    return speed * tan_wheel / effective_wheelbase(wheelbase, gradient, speed)


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


def fit_gradients(
    tan_wheel: np.ndarray,
    speed: np.ndarray,
    yaw_rate: np.ndarray,
    weights: np.ndarray,
    wheelbase: float,
    bounds: tuple[float, float],
) -> np.ndarray:
    """Least-squares K (s^2/m) of each wheel-angle history under each sample weighting, held in ``bounds``.

    Minimises ``sum_n w_n ((L + K v_n^2) r_n - v_n tan(delta_n))^2`` for each row of ``tan_wheel``
    and each row of ``weights``.

    Parameters
    ----------
    tan_wheel : numpy.ndarray
        ``tan(delta)`` of G wheel-angle histories, shape (G, N); finite.
    speed, yaw_rate : numpy.ndarray
        Speed (m/s) and yaw rate (rad/s), shape (N,); finite.
    weights : numpy.ndarray
        Sample weights (0 or 1: which samples a fit uses), shape (F, N).
    wheelbase : float
        L (m).
    bounds : tuple of float
        Plausible range of K (:func:`gradient_bounds`); a least-squares K beyond is held at the
        bound (the constrained solution of a one-parameter problem).

    Returns
    -------
    numpy.ndarray
        K, shape (G, F); 0 under a weighting with no cornering at all.
    """
    a = np.where(weights > 0, speed * speed * yaw_rate, 0.0)  # (F, N), d residual / d K
    wa = weights * a
    den = np.einsum("fn,fn->f", wa, a)
    num = (tan_wheel * speed) @ wa.T - wheelbase * (wa @ yaw_rate)
    k = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
    return np.clip(k, *bounds)
