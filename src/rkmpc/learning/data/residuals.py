"""Control residuals: applied command minus what the kinematic model needed.

The residual Koopman model of Fu et al., *Residual Koopman Model Predictive
Control for Enhanced Vehicle Dynamics with Small On-Track Data Input*
(Sec. IV-A, the "control residual" figure), is trained on
``dU = U_r - U_p``: for an observed transition, ``U_r`` is the command that
was actually applied and ``U_p`` the input under which the nominal kinematic
bicycle (paper Eq. 1) reproduces the same transition. ``dU`` is zero on a car
that is exactly the kinematic model, and otherwise measures the input
correction the real car needs (understeer, actuator lag, speed-loop error).

``U_p`` is found by inverting :func:`rkmpc.vehicle.kinematic.kinematic_step`
exactly: with a constant input the kinematic car drives a circular arc, which
is fixed by its length and its heading change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.core.angles import wrap_angle
from rkmpc.core.validation import require_positive_value
from rkmpc.learning.data.dataset import TransitionDataset

#: Below this travelled distance (m) the wheel angle of a step is undefined and set to 0.
MIN_DISTANCE = 1e-9
#: Below this half heading change (rad) the chord factor uses its series.
_SERIES_LIMIT = 1e-4


def arc_geometry(pose: np.ndarray, next_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed arc length (m), heading change (rad) and direction error (rad) of each step."""
    p = np.asarray(pose, dtype=float)
    q = np.asarray(next_pose, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or q.shape != p.shape:
        raise ValueError(f"pose and next_pose must both have shape (N, 3), got {p.shape} and {q.shape}")
    dpsi = wrap_angle(q[:, 2] - p[:, 2])
    half = 0.5 * dpsi
    dx = q[:, 0] - p[:, 0]
    dy = q[:, 1] - p[:, 1]
    chord = np.hypot(dx, dy)
    # Along-chord direction of the kinematic arc: the mean heading of the step.
    mid = p[:, 2] + half
    along = dx * np.cos(mid) + dy * np.sin(mid)
    backwards = along < 0.0
    # Arc length from the chord: l = c * (dpsi/2) / sin(dpsi/2); series near zero.
    small = np.abs(half) < _SERIES_LIMIT
    safe_half = np.where(small, 1.0, half)
    factor = np.where(small, 1.0 + half * half / 6.0, safe_half / np.sin(safe_half))
    length = np.where(backwards, -1.0, 1.0) * chord * factor
    # Angle between the displacement and the chord direction (forward or backward).
    heading_of_chord = mid + np.where(backwards, math.pi, 0.0)
    direction = np.where(chord > MIN_DISTANCE, wrap_angle(np.arctan2(dy, dx) - heading_of_chord), 0.0)
    return length, dpsi, direction


def kinematic_inverse(pose: np.ndarray, next_pose: np.ndarray, wheelbase: float, dt: float) -> np.ndarray:
    """The constant input that moves the kinematic bicycle from ``pose`` to ``next_pose``.

    With ``[v, delta]`` held for ``dt`` the kinematic model (paper Eq. 1,
    integrated exactly by :func:`rkmpc.vehicle.kinematic.kinematic_step`)
    drives an arc of length ``l = v dt`` and turns by
    ``dpsi = l tan(delta) / L``; the chord between the end points has length
    ``c = l sin(dpsi / 2) / (dpsi / 2)`` and points along the mean heading
    ``yaw + dpsi / 2``. Inverting:

    * ``dpsi = wrap(yaw' - yaw)`` in ``(-pi, pi]``;
    * ``l = c (dpsi / 2) / sin(dpsi / 2)`` (``-> c`` as ``dpsi -> 0``),
      negative when the displacement points backwards relative to the mean
      heading;
    * ``v_p = l / dt`` and ``delta_p = atan(L dpsi / l)`` (0 when
      ``|l| < 1e-9`` m, where any wheel angle gives the same step).

    A real car also slips sideways, so its displacement is generally not
    along the arc's chord. The inverse matches the heading change and the
    travelled distance and ignores that direction error;
    :func:`control_residuals` reports it as a diagnostic. Pure turning on the
    spot (heading change without travel) has no kinematic input and gives
    ``[0, 0]``.

    Parameters
    ----------
    pose : numpy.ndarray, shape (N, 3)
        ``[x, y, yaw]`` (m, m, rad) at the start of each step.
    next_pose : numpy.ndarray, shape (N, 3)
        ``[x, y, yaw]`` at the end of each step.
    wheelbase : float
        ``L`` (m), > 0.
    dt : float
        Step length (s), > 0.

    Returns
    -------
    numpy.ndarray, shape (N, 2)
        ``U_p = [v_p (m/s), delta_p (rad)]``.
    """
    length_wb = require_positive_value(wheelbase, "wheelbase")
    step = require_positive_value(dt, "dt")
    length, dpsi, _ = arc_geometry(pose, next_pose)
    moving = np.abs(length) >= MIN_DISTANCE
    safe = np.where(moving, length, 1.0)
    steer = np.where(moving, np.arctan(length_wb * dpsi / safe), 0.0)
    return np.stack([length / step, steer], axis=1)


@dataclass(frozen=True, eq=False)
class ResidualLabels:
    """Control residuals of a data set, one row per transition.

    Parameters
    ----------
    applied : numpy.ndarray, shape (N, 2)
        ``U_r``, the command applied during the step, ``[speed (m/s), steer (rad)]``.
    nominal : numpy.ndarray, shape (N, 2)
        ``U_p``, the input under which the kinematic model makes the observed
        heading change and travelled distance (:func:`kinematic_inverse`).
    delta : numpy.ndarray, shape (N, 2)
        ``dU = U_r - U_p`` (m/s, rad).
    direction_error : numpy.ndarray, shape (N,)
        Angle (rad) from the kinematic arc's chord direction to the observed
        displacement; positive when the car moved to the left of the arc
        (it slid outwards in a right turn, or its body side-slipped left).
        Diagnostic only.
    """

    applied: np.ndarray
    nominal: np.ndarray
    delta: np.ndarray
    direction_error: np.ndarray


def control_residuals(data: TransitionDataset, wheelbase: float) -> ResidualLabels:
    """Residual labels ``dU = U_r - U_p`` of every transition.

    Parameters
    ----------
    data : TransitionDataset
        Observed transitions; ``U_r`` is ``data.command``.
    wheelbase : float
        Wheelbase ``L`` (m) of the nominal kinematic model.

    Returns
    -------
    ResidualLabels
    """
    length_wb = require_positive_value(wheelbase, "wheelbase")
    poses = data.poses()
    next_poses = data.next_poses()
    nominal = kinematic_inverse(poses, next_poses, length_wb, data.dt)
    _, _, direction = arc_geometry(poses, next_poses)
    applied = np.array(data.command, dtype=float)
    return ResidualLabels(
        applied=applied,
        nominal=nominal,
        delta=applied - nominal,
        direction_error=direction,
    )
