"""Time-indexed reference trajectories along a path driven at a speed profile."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rkmpc.core.angles import TWO_PI as _TWO_PI
from rkmpc.core.angles import wrap_scalar
from rkmpc.core.errors import ParameterError
from rkmpc.track.path import Path, Projection
from rkmpc.track.speed_profile import SpeedProfile

__all__ = ["Reference", "ReferenceHorizon"]

FloatArray = NDArray[np.float64]

# Spacing of the reference's path table (m) and bounds on its size.
_TABLE_SPACING = 0.02
_TABLE_MIN = 2000
_TABLE_MAX = 20000

_interp = np.interp

_new_object = object.__new__
_add = np.add
_subtract = np.subtract
_multiply = np.multiply
_divide = np.divide
_copyto = np.copyto


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

    def head(self, n_steps: int) -> ReferenceHorizon:
        """The first ``n_steps`` steps of this horizon (arrays of shape ``(n_steps + 1,)``)."""
        k = n_steps + 1
        return ReferenceHorizon(
            self.s[:k], self.x[:k], self.y[:k], self.theta[:k], self.v[:k], self.delta[:k]
        )

    def as_array(self) -> FloatArray:
        """Stack the reference as an ``(n + 1, 5)`` array with columns ``x, y, theta, v, delta``."""
        return np.column_stack([self.x, self.y, self.theta, self.v, self.delta])


def _pair_rows(table: FloatArray) -> FloatArray:
    """Rows ``i`` and ``i + 1`` of ``table`` as column ``i``, shape ``(2 * ncols, len(table) - 1)``."""
    return np.ascontiguousarray(np.vstack([table[:-1].T, table[1:].T]))


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

        # Hot-path constants of horizon().  Profile grid as lists, for the scalar
        # interpolation t(s0), and its mean spacing for the first index guess.
        self._sp_list: list[float] = s_prof.tolist()
        self._tp_list: list[float] = self._t_prof.tolist()
        self._sp_inv = (s_prof.size - 1) / length
        # Columns (table[i], table[i + 1]) stacked, shape (10, n_tab), so that one
        # take() fetches both ends of every interval of the horizon, row by row.
        self._table_pairs = _pair_rows(self._table)
        # A horizon whose last time is before _t_fast neither crosses the start line
        # nor comes within two table steps of s = L: no lap arithmetic, no clipping.
        j_fast = int(np.searchsorted(s_prof, length - 2.0 * self._ds, side="right")) - 1
        self._t_fast = float(self._t_prof[max(j_fast, 0)])
        # Scratch buffers per (thread, n_steps, dt), see _horizon_buffers.
        self._buffers: dict[tuple[int, int, float], tuple[Any, ...]] = {}

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_buffers"] = {}  # scratch space: neither pickled nor shared between copies
        state.pop("_table_pairs")  # derived from _table, rebuilt on unpickling
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._table_pairs = _pair_rows(self._table)

    def _horizon_buffers(self, key: tuple[int, int, float]) -> tuple[Any, ...]:
        """Scratch arrays of :meth:`horizon` for ``key = (thread, n_steps, dt)``."""
        n1 = key[1] + 1
        offsets = key[2] * np.arange(n1)
        t = np.empty(n1)
        u = np.empty(n1)
        idx = np.empty(n1, dtype=np.intp)
        weights = np.empty((2, n1))
        pairs = np.empty((10, n1))
        pairs3 = pairs.reshape(2, 5, n1)
        bufs = (
            offsets,
            float(offsets[-1]),
            t,
            u,
            idx,
            weights[0],
            weights[1],
            weights[:, None, :],
            pairs,
            pairs3,
            pairs3[0],
            pairs3[1],
        )
        self._buffers[key] = bufs
        return bufs

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
        s0w = s0 % length
        key = (threading.get_ident(), n_steps, dt)
        bufs = self._buffers.get(key)
        if bufs is None:
            bufs = self._horizon_buffers(key)
        (offsets, last_offset, t, u, idx, w0, w1, w3, pairs, pairs3, lower, upper) = bufs
        # t0 = np.interp(s0w, s_prof, t_prof), as the scalar case of numpy's kernel.
        x = float(s0w)
        sp = self._sp_list
        tp = self._tp_list
        last = len(sp) - 1
        j = int(x * self._sp_inv)
        if j > last:
            j = last
        elif j < 0:
            j = 0
        while j > 0 and sp[j] > x:
            j -= 1
        while j < last and sp[j + 1] <= x:
            j += 1
        if x < sp[0]:
            t0 = tp[0]
        elif j == last or sp[j] == x:
            t0 = tp[j]
        else:
            t0 = (tp[j + 1] - tp[j]) / (sp[j + 1] - sp[j]) * (x - sp[j]) + tp[j]
        if not (t0 + last_offset < self._t_fast and x == x):
            return self._horizon_general(s0w, t0, n_steps, dt)
        # No lap crossing: laps == 0, s_lap < length - 2 ds, no index clipping.
        _add(offsets, t0, out=t)
        s_lap = _interp(t, self._t_prof, self._s_prof)
        s_lap[0] = s0w
        _divide(s_lap, self._ds, out=u)
        _copyto(idx, u, casting="unsafe")
        _subtract(u, idx, out=w1)
        _subtract(1.0, w1, out=w0)
        self._table_pairs.take(idx, axis=1, out=pairs)
        _multiply(pairs3, w3, out=pairs3)
        vals = _add(lower, upper)  # rows x, y, theta, v, delta
        th0 = float(vals[2, 0])
        # Shift theta so that theta[0] lies in (-pi, pi].
        wrapped0 = wrap_scalar(th0)
        theta = vals[2] + (wrapped0 - th0)
        # ReferenceHorizon(...) without the frozen dataclass's per-field __setattr__.
        out = _new_object(ReferenceHorizon)
        attrs = out.__dict__
        attrs["s"] = s_lap
        attrs["x"] = vals[0]
        attrs["y"] = vals[1]
        attrs["theta"] = theta
        attrs["v"] = vals[3]
        attrs["delta"] = vals[4]
        return out

    def _horizon_general(self, s0w: float, t0: float, n_steps: int, dt: float) -> ReferenceHorizon:
        """:meth:`horizon` for any start, lap crossings included (plain vectorised code)."""
        lap_time = self.lap_time
        t = t0 + dt * np.arange(n_steps + 1)
        laps = np.floor(t / lap_time)
        s_lap = np.interp(t - laps * lap_time, self._t_prof, self._s_prof)
        # Make the first point exactly s0 (interpolation round trip is not exact).
        s_lap[0] = s0w
        return self._tabulated(s_lap, laps)

    def _tabulated(self, s_lap: FloatArray, laps: FloatArray) -> ReferenceHorizon:
        """The path table at arc lengths ``s_lap`` within lap ``laps``, theta from (-pi, pi]."""
        u = s_lap / self._ds
        idx = np.minimum(u.astype(np.intp), self._n_tab - 1)
        frac = (u - idx)[:, None]
        tab = self._table
        vals = tab[idx] * (1.0 - frac) + tab[idx + 1] * frac
        theta = vals[:, 2] + self._theta_per_lap * laps
        # Shift theta so that theta[0] lies in (-pi, pi].
        th0 = theta[0]
        wrapped0 = wrap_scalar(th0)
        theta = theta + (wrapped0 - th0)
        s_out = np.where(s_lap >= self._length, s_lap - self._length, s_lap)
        return ReferenceHorizon(
            s=s_out,
            x=vals[:, 0],
            y=vals[:, 1],
            theta=theta,
            v=vals[:, 3],
            delta=vals[:, 4],
        )

    def along(self, s0: float, distances: FloatArray) -> ReferenceHorizon:
        """The reference at ``s0`` and at the arc lengths ``s0 + distances`` ahead of it.

        Where :meth:`horizon` spaces its points by the time the speed profile takes,
        this spaces them by distance: the points a car reaches at any other speed.

        Parameters
        ----------
        s0 : float
            Arc length (m) of the first point, any real; wrapped modulo the path length.
        distances : numpy.ndarray
            Distances (m) of the following points from ``s0``, shape (n,), non-decreasing and
            >= 0 (not checked here: the residual QP's are cumulative sums of non-negative steps);
            they may run over the start line.

        Returns
        -------
        ReferenceHorizon
            Arrays of shape ``(n + 1,)``; ``theta`` continuous from ``theta[0]`` in (-pi, pi],
            ``v`` the speed profile's at each point.
        """
        s = np.empty(len(distances) + 1)
        s[0] = s0 % self._length
        np.add(s[0], distances, out=s[1:])
        laps = np.floor(s / self._length)
        return self._tabulated(s - laps * self._length, laps)

    def project(self, x: float, y: float, s_hint: float | None = None) -> Projection:
        """Project a point onto the reference path (see :meth:`Path.project`)."""
        if s_hint is None:
            return self.path.project(x, y)
        return self.path.projector.project_hinted(float(x), float(y), float(s_hint))
