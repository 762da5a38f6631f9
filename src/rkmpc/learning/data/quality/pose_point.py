"""Where on the car the pose is: the point whose sideways motion in turns the steps show.

The nominal model (paper Eq. 1) moves the car along its heading. A real car's rear axle nearly
does (its tyres barely slide at a 1:10 car's pace), so a point ``l`` ahead of it moves at the angle
``atan(l * kappa)`` to the heading in a turn of curvature ``kappa``: the centre of gravity
(``l = lr``), where rkmpc's data sets hold the pose, drifts to the inside of every turn. Fitting
``l`` to the steps of a recording tells whether its pose is the point the import assumed: a log
whose notes do not say (the FrictionMaps logger's) or a pose frame set wrongly shows an ``l`` far
from ``lr``.

The fit: each step's direction error (angle from its heading to its displacement) against a
constant (a heading offset), ``kappa`` (the point) and ``v * r`` (real slip grows with the lateral
acceleration), over the steps faster than :data:`MIN_SPEED`; ordinary least squares, then
:data:`ROUNDS` refits without the steps more than :data:`TRIM` robust standard deviations off
(particle-filter noise and the odd jump the jump rule let through). Where the speed hardly varies,
``v * r`` is ``v**2 * kappa`` and cannot be told from ``kappa``: the slip term is then left out
(:data:`MAX_COLLINEARITY`), and ``l`` holds what slip there is.
"""

from __future__ import annotations

import numpy as np

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.quality.records import PosePoint
from rkmpc.learning.data.residuals import arc_geometry

__all__ = ["MAX_COLLINEARITY", "MIN_SAMPLES", "MIN_SPEED", "ROUNDS", "TRIM", "pose_point"]

#: Steps slower than this (m/s) are left out: their direction is mostly pose noise.
MIN_SPEED = 0.5
#: Fewer usable steps than this: no fit.
MIN_SAMPLES = 50
#: Steps more than this many robust standard deviations off the fit are left out of the next one.
TRIM = 3.0
#: Refits after the first.
ROUNDS = 5
#: The smallest spread of curvature (1/m, standard deviation) that lets ``l`` be told apart.
MIN_CURVATURE_SPREAD = 0.05
#: Above this correlation of ``kappa`` and ``v * r`` the slip term is left out.
MAX_COLLINEARITY = 0.95
#: ``l`` agrees with the expected point within 3 standard errors or this fraction of it.
RELATIVE_TOLERANCE = 0.1


def pose_point(data: TransitionDataset, expected: float | None = None) -> PosePoint | None:
    """The fitted pose point of ``data`` (module docstring); None when the data cannot tell.

    Parameters
    ----------
    data : TransitionDataset
        Transitions on one period.
    expected : float or None
        Where the pose should be, ahead of the rear axle (m): the car's ``lr`` for rkmpc's data
        sets (the centre of gravity). None: no verdict.
    """
    length, turn, direction = arc_geometry(data.poses(), data.next_poses())
    dt = data.dt
    speed = length / dt
    moving = speed > MIN_SPEED
    if int(moving.sum()) < MIN_SAMPLES:
        return None
    curvature = turn[moving] / length[moving]
    if float(np.std(curvature)) < MIN_CURVATURE_SPREAD:
        return None
    lateral = speed[moving] * turn[moving] / dt
    x = np.stack([np.ones(curvature.size), curvature, lateral], axis=1)
    if abs(float(np.corrcoef(curvature, lateral)[0, 1])) > MAX_COLLINEARITY:
        x = x[:, :2]
    y = direction[moving]
    keep = np.ones(y.size, dtype=bool)
    for _ in range(ROUNDS + 1):
        coef = np.linalg.lstsq(x[keep], y[keep], rcond=None)[0]
        residual = y - x @ coef
        spread = 1.4826 * float(np.median(np.abs(residual[keep] - np.median(residual[keep]))))
        if spread <= 0.0:
            break
        keep = np.abs(residual) <= TRIM * spread
        if int(keep.sum()) < MIN_SAMPLES:
            return None
    residual = (y - x @ coef)[keep]
    n = int(keep.sum())
    variance = float(residual @ residual) / max(n - x.shape[1], 1)
    error = float(np.sqrt(variance * np.linalg.inv(x[keep].T @ x[keep])[1, 1]))
    total = float(np.var(y[keep]))
    offset = float(coef[1])
    consistent = None
    if expected is not None:
        consistent = abs(offset - expected) <= max(3.0 * error, RELATIVE_TOLERANCE * abs(expected))
    return PosePoint(
        offset_m=offset,
        std_error_m=error,
        expected_m=expected,
        r2=1.0 - float(np.var(residual)) / total if total > 0.0 else 0.0,
        samples=n,
        consistent=consistent,
    )
