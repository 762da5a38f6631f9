"""Curvature-limited speed profiles with acceleration and braking limits.

The profile is computed on a uniform arc-length grid over one lap:

1. ``v_max(s) = min(max_speed, sqrt(lateral_accel / |kappa(s)|))`` where
   ``kappa`` is the path curvature at the grid points, optionally smoothed by a
   periodic moving average of ``curvature_smoothing`` metres (off by default:
   the spline curvature is already continuous, and smoothing lowers curvature
   peaks so the lateral limit would only hold for the smoothed curvature);
   then ``v_max`` is raised to at least ``min_speed`` (the floor wins over the
   lateral limit where they conflict);
2. a forward pass limits acceleration, ``v[i+1]^2 <= v[i]^2 + 2 * accel * ds``;
3. a backward pass limits braking, ``v[i]^2 <= v[i+1]^2 + 2 * brake_decel * ds``.

The limits are independent (no friction circle).  The passes are made
periodic by starting them at the grid point with the lowest ``v_max``: the
speed there cannot be lowered by either pass, so the result is consistent
across the start line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rkmpc.core.errors import ParameterError
from rkmpc.track.path import Path

__all__ = ["SpeedLimits", "SpeedProfile", "speed_profile"]

FloatArray = NDArray[np.float64]

# Default grid: spacing 0.1 m, between 500 and 20000 points per lap.
_DEFAULT_DS = 0.1
_MIN_POINTS = 500
_MAX_POINTS = 20000


@dataclass(frozen=True)
class SpeedLimits:
    """Limits used to build a speed profile.

    Parameters
    ----------
    lateral_accel : float, default 4.0
        Largest lateral acceleration ``v^2 |kappa|`` (m/s^2).
    brake_decel : float, default 2.5
        Largest braking deceleration (m/s^2).
    accel : float, default 2.5
        Largest (traction-limited) acceleration (m/s^2).
    max_speed : float, default 5.0
        Top speed (m/s).
    min_speed : float, default 0.5
        Speed floor (m/s), must be below ``max_speed``.
    curvature_rate : float or None, default None
        Largest rate of change of the path curvature the car is asked to
        follow, ``v |dkappa/ds|`` (1/(m s)); None for no such limit. A steering
        servo with a lag cannot follow curvature that changes faster than this
        without falling behind (in chicanes, for example); for a car with
        wheelbase ``L`` it bounds the kinematic wheel-angle rate by about
        ``L * curvature_rate``.

    Raises
    ------
    ParameterError
        If a value is not finite and positive or ``min_speed >= max_speed``.
    """

    lateral_accel: float = 4.0
    brake_decel: float = 2.5
    accel: float = 2.5
    max_speed: float = 5.0
    min_speed: float = 0.5
    curvature_rate: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.name == "curvature_rate":
                continue
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"SpeedLimits.{f.name} must be finite and > 0, got {value!r}")
        if self.min_speed >= self.max_speed:
            raise ParameterError(
                f"SpeedLimits.min_speed ({self.min_speed}) must be below max_speed ({self.max_speed})"
            )

    def at_pace(self, lateral_accel: float | None = None, max_speed: float | None = None) -> SpeedLimits:
        """These limits at another pace: a lateral-acceleration limit (m/s^2) and a top speed (m/s).

        Braking and traction scale with the lateral-acceleration limit (the same tyres asked
        for more grip in every direction); the speed floor and the curvature-rate limit (a
        property of the steering servo) stay. Either argument None keeps the current value.
        """
        lateral = self.lateral_accel if lateral_accel is None else lateral_accel
        ratio = lateral / self.lateral_accel if math.isfinite(lateral) and lateral > 0 else math.nan
        return replace(
            self,
            lateral_accel=lateral,
            brake_decel=self.brake_decel * ratio,
            accel=self.accel * ratio,
            max_speed=self.max_speed if max_speed is None else max_speed,
        )


class SpeedProfile:
    """Speed as a periodic function of arc length.

    Parameters
    ----------
    s : ndarray, shape (n,)
        Uniform arc-length grid over one lap (m), ``s[0] = 0``, ``s[-1] < length``.
    v : ndarray, shape (n,)
        Speed at each grid point (m/s), > 0.
    length : float
        Lap length (m).

    Attributes
    ----------
    lap_time : float
        Time for one lap at this profile (s), trapezoidal in ``1/v``.
    """

    def __init__(self, s: FloatArray, v: FloatArray, length: float) -> None:
        s = np.asarray(s, dtype=float)
        v = np.asarray(v, dtype=float)
        if s.ndim != 1 or s.shape != v.shape or s.size < 2:
            raise ParameterError("SpeedProfile: s and v must be 1-D arrays of equal length >= 2")
        if not (np.all(np.isfinite(v)) and np.all(v > 0.0)):
            raise ParameterError("SpeedProfile: speeds must be finite and > 0")
        self.s = s
        self.v = v
        self.length = float(length)
        self._s_ext = np.append(s, self.length)
        self._v_ext = np.append(v, v[0])
        ds = np.diff(self._s_ext)
        self.lap_time = float(np.sum(2.0 * ds / (self._v_ext[:-1] + self._v_ext[1:])))

    def speed(self, s: ArrayLike) -> FloatArray | float:
        """Speed (m/s) at arc length ``s`` (m, any real; periodic linear interpolation)."""
        sw = np.mod(np.asarray(s, dtype=float), self.length)
        out = np.interp(sw, self._s_ext, self._v_ext)
        return float(out) if np.ndim(out) == 0 else np.asarray(out)

    def __repr__(self) -> str:
        return f"SpeedProfile(n={self.s.size}, lap_time={self.lap_time:.3f} s, v_max={self.v.max():.3f} m/s)"


def _periodic_moving_average(values: FloatArray, window: int) -> FloatArray:
    if window <= 1:
        return values.copy()
    half = window // 2
    padded = np.concatenate([values[-half:], values, values[: window - half - 1]])
    csum = np.concatenate([[0.0], np.cumsum(padded)])
    return (csum[window:] - csum[:-window]) / window


def speed_profile(
    path: Path, limits: SpeedLimits, ds: float | None = None, *, curvature_smoothing: float = 0.0
) -> SpeedProfile:
    """Compute the speed profile of a closed path.

    Parameters
    ----------
    path : Path
        Closed path to drive.
    limits : SpeedLimits
        Acceleration and speed limits.
    ds : float, optional
        Grid spacing (m).  Default: about 0.1 m, with 500 to 20000 points per lap.
        The actual spacing divides the lap length evenly.
    curvature_smoothing : float, default 0.0
        Length (m) of the periodic moving average applied to the curvature
        before the lateral limit; 0 disables it.

    Returns
    -------
    SpeedProfile
        Profile on a uniform grid over one lap (see the module docstring).
    """
    length = path.length
    if ds is None:
        n = int(np.clip(math.ceil(length / _DEFAULT_DS), _MIN_POINTS, _MAX_POINTS))
    else:
        if not (math.isfinite(ds) and ds > 0.0):
            raise ParameterError(f"speed_profile: ds must be finite and > 0, got {ds!r}")
        n = max(math.ceil(length / ds - 1e-9), 4)
    step = length / n
    s = (np.arange(n) * step).astype(np.float64)
    kappa = np.asarray(path.curvature(s), dtype=float)
    if not (math.isfinite(curvature_smoothing) and curvature_smoothing >= 0.0):
        raise ParameterError(
            f"speed_profile: curvature_smoothing must be finite and >= 0, got {curvature_smoothing!r}"
        )
    window = min(round(curvature_smoothing / step), n)
    if window > 1:
        kappa = _periodic_moving_average(kappa, window)
    abs_k = np.maximum(np.abs(kappa), 1e-12)
    v_max = np.minimum(limits.max_speed, np.sqrt(limits.lateral_accel / abs_k))
    if limits.curvature_rate is not None:
        dk_ds = np.abs(np.gradient(np.concatenate([kappa[-1:], kappa, kappa[:1]]), step)[1:-1])
        v_max = np.minimum(v_max, limits.curvature_rate / np.maximum(dk_ds, 1e-12))
    v_max = np.maximum(v_max, limits.min_speed)

    start = int(np.argmin(v_max))
    v2 = np.roll(v_max, -start) ** 2
    # Append the start point again so the passes see the wrap-around.
    v2 = np.append(v2, v2[0])
    acc = 2.0 * limits.accel * step
    brk = 2.0 * limits.brake_decel * step
    vals = v2.tolist()
    for i in range(n):
        cap = vals[i] + acc
        if vals[i + 1] > cap:
            vals[i + 1] = cap
    for i in range(n - 1, -1, -1):
        cap = vals[i + 1] + brk
        if vals[i] > cap:
            vals[i] = cap
    v = np.sqrt(np.asarray(vals[:n]))
    v = np.roll(v, start)
    return SpeedProfile(s, v, length)
