"""Time-indexed reference trajectories along a path driven at a speed profile."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rkmpc.errors import ParameterError
from rkmpc.track.path import Path, Projection
from rkmpc.track.speed_profile import SpeedProfile

__all__ = ["Reference", "ReferenceHorizon"]

FloatArray = NDArray[np.float64]

_TWO_PI = 2.0 * math.pi
# Spacing of the reference's path table (m) and bounds on its size.
_TABLE_SPACING = 0.02
_TABLE_MIN = 2000
_TABLE_MAX = 20000


@dataclass(frozen=True)
class ReferenceHorizon:
    """Reference states over a prediction horizon of ``n`` steps.

    All arrays have shape ``(n + 1,)``; index 0 is the current time.

    Parameters
    ----------
    s : ndarray
        Arc length along the path (m), wrapped into ``[0, length)``.
    x, y : ndarray
        Reference position (m).
    theta : ndarray
        Reference heading (rad), continuous along the horizon, ``theta[0]`` in (-pi, pi].
    v : ndarray
        Reference speed (m/s).
    delta : ndarray
        Feed-forward kinematic steering angle ``atan(wheelbase * curvature)`` (rad).
    """

    s: FloatArray
    x: FloatArray
    y: FloatArray
    theta: FloatArray
    v: FloatArray
    delta: FloatArray

    def as_array(self) -> FloatArray:
        """Stack the reference as an ``(n + 1, 5)`` array with columns ``x, y, theta, v, delta``."""
        return np.column_stack([self.x, self.y, self.theta, self.v, self.delta])


class Reference:
    """Reference generator: a path, a speed profile along it, and a wheelbase.

    At construction the path is tabulated on a uniform arc-length grid and the
    time ``t(s)`` to reach each profile grid point from ``s = 0`` is integrated
    (trapezoid in ``1/v``), so that :meth:`horizon` needs only a few vectorised
    interpolations.

    Parameters
    ----------
    path : Path
        Path to follow (the profile must have been computed on it).
    profile : SpeedProfile
        Speed along ``path``.
    wheelbase : float
        Vehicle wheelbase (m) used for the feed-forward steering angle.

    Raises
    ------
    ParameterError
        If ``wheelbase`` is not finite and positive, or the profile length
        does not match the path.
    """

    def __init__(self, path: Path, profile: SpeedProfile, wheelbase: float) -> None:
        if not (math.isfinite(wheelbase) and wheelbase > 0.0):
            raise ParameterError(f"Reference: wheelbase must be finite and > 0, got {wheelbase!r}")
        if abs(profile.length - path.length) > 1e-6 * path.length:
            raise ParameterError(
                f"Reference: profile length {profile.length:.6g} m does not match "
                f"path length {path.length:.6g} m"
            )
        self.path = path
        self.profile = profile
        self.wheelbase = float(wheelbase)
        length = path.length
        self._length = length

        # Path table on a uniform grid including the closing point s = L.
        n_tab = int(np.clip(math.ceil(length / _TABLE_SPACING), _TABLE_MIN, _TABLE_MAX))
        self._ds = length / n_tab
        self._n_tab = n_tab
        s_tab = np.arange(n_tab + 1) * self._ds
        pos = path.position(s_tab)
        theta = np.asarray(path.heading_unwrapped(s_tab), dtype=float)
        kappa = np.asarray(path.curvature(s_tab), dtype=float)
        delta = np.arctan(self.wheelbase * kappa)
        v = np.asarray(profile.speed(s_tab), dtype=float)
        # Columns: x, y, theta (unwrapped within the lap), v, delta.
        self._table = np.column_stack([pos[:, 0], pos[:, 1], theta, v, delta])
        self._theta_per_lap = _TWO_PI * path.winding_number

        # Time parametrisation on the profile grid (with the closing point).
        s_prof = np.append(profile.s, length)
        v_prof = np.append(profile.v, profile.v[0])
        dt = 2.0 * np.diff(s_prof) / (v_prof[:-1] + v_prof[1:])
        self._s_prof = s_prof
        self._t_prof = np.concatenate([[0.0], np.cumsum(dt)])
        self.lap_time = float(self._t_prof[-1])

    def horizon(self, s0: float, n_steps: int, dt: float) -> ReferenceHorizon:
        """Reference over ``n_steps`` steps of ``dt`` starting at arc length ``s0``.

        Entry ``k`` is the path point reached ``k * dt`` seconds after passing
        ``s0`` when driving the speed profile; the arc length increases
        monotonically (wrapping across the start line), ``theta`` stays
        continuous.

        Parameters
        ----------
        s0 : float
            Current arc length (m), any real; wrapped modulo the path length.
        n_steps : int
            Number of steps ``n`` (>= 0).
        dt : float
            Step length (s), > 0.

        Returns
        -------
        ReferenceHorizon
            Arrays of shape ``(n_steps + 1,)``.
        """
        if n_steps < 0 or not dt > 0.0:
            raise ParameterError(f"Reference.horizon: need n_steps >= 0 and dt > 0, got {n_steps!r}, {dt!r}")
        length = self._length
        lap_time = self.lap_time
        s0w = s0 % length
        t0 = float(np.interp(s0w, self._s_prof, self._t_prof))
        t = t0 + dt * np.arange(n_steps + 1)
        laps = np.floor(t / lap_time)
        s_lap = np.interp(t - laps * lap_time, self._t_prof, self._s_prof)
        # Make the first point exactly s0 (interpolation round trip is not exact).
        s_lap[0] = s0w
        u = s_lap / self._ds
        idx = np.minimum(u.astype(np.intp), self._n_tab - 1)
        frac = (u - idx)[:, None]
        tab = self._table
        vals = tab[idx] * (1.0 - frac) + tab[idx + 1] * frac
        theta = vals[:, 2] + self._theta_per_lap * laps
        # Shift theta so that theta[0] lies in (-pi, pi].
        th0 = theta[0]
        wrapped0 = math.pi - math.fmod(math.pi - th0, _TWO_PI)
        if wrapped0 <= -math.pi:
            wrapped0 += _TWO_PI
        elif wrapped0 > math.pi:
            wrapped0 -= _TWO_PI
        theta = theta + (wrapped0 - th0)
        s_out = np.where(s_lap >= length, s_lap - length, s_lap)
        return ReferenceHorizon(
            s=s_out,
            x=vals[:, 0],
            y=vals[:, 1],
            theta=theta,
            v=vals[:, 3],
            delta=vals[:, 4],
        )

    def project(self, x: float, y: float, s_hint: float | None = None) -> Projection:
        """Project a point onto the reference path (see :meth:`Path.project`)."""
        return self.path.project(x, y, s_hint=s_hint)
