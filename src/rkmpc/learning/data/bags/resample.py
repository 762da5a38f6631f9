"""From time-stamped odometry and commands to transitions on the control period (no ROS needed).

* **Frame.** Odometry of the rear axle's centre is moved to the centre of gravity, ``lr`` ahead
  along the heading: ``x += lr cos(yaw)``, ``y += lr sin(yaw)``; the lateral velocity in the car's
  frame gains ``lr * yaw_rate`` (the velocity of a point ``lr`` ahead on a turning body); the
  forward velocity and the yaw rate are the same at both points.
* **Grid.** Samples are taken every ``dt`` from the first command's stamp on (so a controller
  running at ``dt`` has a command at every sample and no sample precedes the first command), at
  the instants an odometry stretch covers: an odometry gap longer than ``gap`` splits the stretches.
* **Odometry.** Each sample interpolates the odometry linearly between the two messages around it
  (at a message's stamp: that message, exactly). The heading is unwrapped before and wrapped to
  ``(-pi, pi]`` after; the side-slip angle ``atan2(vy, vx)`` is computed from the interpolated
  velocities, NaN below ``min_slip_speed``.
* **Commands.** Zero-order hold: each sample takes the last command stamped at or before it (or up
  to ``tolerance`` after it, the controller's timer jitter); a command older than ``gap`` is not
  held, and the sample is unusable, as is one whose speed along the heading is negative.
* **Steer angle.** Interpolated like the odometry where two steer messages at most ``gap`` apart
  surround the sample, NaN elsewhere.
* **Transitions.** Two consecutive samples of one stretch, both usable, make a transition; an
  unbroken run of transitions is an episode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.core.angles import wrap_angle
from rkmpc.learning.data.bags.read import ODOM_FIELDS, Stream

__all__ = ["Samples", "Transitions", "odometry_at_cog", "resample", "stretches", "transitions"]

_NS = 1_000_000_000
_X, _Y, _YAW, _VX, _VY, _R = range(len(ODOM_FIELDS))


@dataclass(frozen=True, eq=False)
class Samples:
    """Odometry on the control grid with the commands held over it, ``M`` samples.

    Parameters
    ----------
    stamps : numpy.ndarray, shape (M,), int64
        Time of each sample (ns, the bag's clock).
    grid : numpy.ndarray, shape (M,), int64
        Index of each sample on the grid (``stamps = origin + grid * dt``).
    segment : numpy.ndarray, shape (M,), int64
        The odometry stretch (between gaps) each sample lies in.
    obs : numpy.ndarray, shape (M, 7)
        Observations (:data:`~rkmpc.core.observation.OBSERVATION_FIELDS`, SI units).
    command : numpy.ndarray, shape (M, 2)
        The command held at each sample, ``[speed (m/s), steer (rad)]``.
    usable : numpy.ndarray, shape (M,), bool
        A fresh command is held and the speed is not negative.
    """

    stamps: np.ndarray
    grid: np.ndarray
    segment: np.ndarray
    obs: np.ndarray
    command: np.ndarray
    usable: np.ndarray

    def __len__(self) -> int:
        return int(self.stamps.shape[0])


@dataclass(frozen=True, eq=False)
class Transitions:
    """The arrays of a :class:`~rkmpc.learning.data.dataset.TransitionDataset`, ``N`` transitions."""

    obs: np.ndarray
    command: np.ndarray
    next_obs: np.ndarray
    episode: np.ndarray
    stamps: np.ndarray

    def __len__(self) -> int:
        return int(self.obs.shape[0])


def odometry_at_cog(values: np.ndarray, lr: float) -> np.ndarray:
    """Odometry rows (columns ``x, y, yaw, vx, vy, yaw_rate``) of the rear axle moved to the CoG.

    Parameters
    ----------
    values : numpy.ndarray, shape (N, 6)
        The rear axle's pose (m, m, rad) and velocities in the car's frame (m/s, m/s, rad/s).
    lr : float
        Centre of gravity to rear axle (m); a negative ``lr`` moves the other way.
    """
    out = np.array(values, dtype=float)
    out[:, _X] += lr * np.cos(out[:, _YAW])
    out[:, _Y] += lr * np.sin(out[:, _YAW])
    out[:, _VY] += lr * out[:, _R]
    return out


def stretches(stamps: np.ndarray, gap_ns: int) -> list[tuple[int, int]]:
    """``(first stamp, last stamp)`` (ns) of every stretch of messages without a gap over ``gap_ns``."""
    breaks = np.flatnonzero(np.diff(stamps) > gap_ns)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [len(stamps) - 1]])
    return [(int(stamps[s]), int(stamps[e])) for s, e in zip(starts, ends, strict=True)]


def _grid(stamps: np.ndarray, origin: int, dt_ns: int, gap_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """Grid indices (>= 0) inside the odometry's stretches, and the stretch of each."""
    grids, segments = [], []
    for k, (first, last) in enumerate(stretches(stamps, gap_ns)):
        lo = max(0, -((origin - first) // dt_ns))  # ceil((first - origin) / dt)
        hi = (last - origin) // dt_ns
        if hi >= lo:
            grids.append(np.arange(lo, hi + 1, dtype=np.int64))
            segments.append(np.full(hi + 1 - lo, k, dtype=np.int64))
    if not grids:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    return np.concatenate(grids), np.concatenate(segments)


def _steer_at(steer: Stream, stamps: np.ndarray, gap_ns: int) -> np.ndarray:
    """The wheel angle (rad) at each stamp, NaN where no two messages ``gap_ns`` apart surround it."""
    known = steer.stamps
    left = np.clip(np.searchsorted(known, stamps, side="right") - 1, 0, len(known) - 1)
    right = np.minimum(left + 1, len(known) - 1)
    close = (known[right] - known[left] <= gap_ns) | (known[left] == stamps)
    inside = (stamps >= known[0]) & (stamps <= known[-1]) & close
    value = np.interp((stamps - known[0]) / _NS, (known - known[0]) / _NS, steer.values[:, 0])
    return np.where(inside, value, math.nan)


def resample(
    odom: Stream,
    drive: Stream,
    steer: Stream | None,
    *,
    dt: float,
    gap: float,
    tolerance: float,
    lr: float = 0.0,
    min_slip_speed: float = 0.5,
    lateral_velocity: bool = True,
    yaw_rate: bool = True,
) -> Samples:
    """Resample odometry onto the control period and hold the commands over it (module docstring).

    Parameters
    ----------
    odom : Stream
        Odometry, columns :data:`~rkmpc.learning.data.bags.read.ODOM_FIELDS`, stamps increasing.
    drive : Stream
        Commands ``[speed (m/s), steer (rad)]``, stamps increasing.
    steer : Stream or None
        Measured wheel angle (rad).
    dt : float
        Control period (s).
    gap : float
        Longest odometry gap (s) inside a stretch; oldest command held (s).
    tolerance : float
        How late (s) a command may be stamped and still count for a sample.
    lr : float
        Distance (m) the odometry's frame lies behind the centre of gravity (0: it is the CoG).
    min_slip_speed : float
        Speed (m/s) below which the side-slip angle is NaN.
    lateral_velocity, yaw_rate : bool
        Whether the twist's ``linear.y`` and ``angular.z`` were measured; False: the side-slip
        angle, the yaw rate is NaN.

    Returns
    -------
    Samples
    """
    dt_ns, gap_ns, tol_ns = (round(value * _NS) for value in (dt, gap, tolerance))
    origin = int(drive.stamps[0])
    grid, segment = _grid(odom.stamps, origin, dt_ns, gap_ns)
    stamps = origin + grid * dt_ns
    values = odometry_at_cog(odom.values, lr) if lr else np.array(odom.values, dtype=float)
    values[:, _YAW] = np.unwrap(values[:, _YAW])
    known = (odom.stamps - origin) / _NS
    at = (stamps - origin) / _NS
    x, y, yaw, vx, vy, rate = (np.interp(at, known, values[:, j]) for j in range(len(ODOM_FIELDS)))
    with np.errstate(invalid="ignore"):
        slip = np.where(np.hypot(vx, vy) >= min_slip_speed, np.arctan2(vy, vx), math.nan)
    if not lateral_velocity:
        slip = np.full(len(stamps), math.nan)
    if not yaw_rate:
        rate = np.full(len(stamps), math.nan)
    wheel = _steer_at(steer, stamps, gap_ns) if steer is not None else np.full(len(stamps), math.nan)
    obs = np.stack([x, y, wrap_angle(yaw), vx, rate, slip, wheel], axis=1)
    held = np.searchsorted(drive.stamps, stamps + tol_ns, side="right") - 1
    fresh = (held >= 0) & (stamps - drive.stamps[np.maximum(held, 0)] <= gap_ns)
    command = drive.values[np.maximum(held, 0)]
    usable = fresh & (vx >= 0.0)
    return Samples(stamps=stamps, grid=grid, segment=segment, obs=obs, command=command, usable=usable)


def transitions(samples: Samples) -> Transitions:
    """Consecutive usable samples of one stretch as transitions, episodes numbered 0, 1, ..."""
    ok = (
        samples.usable[:-1]
        & samples.usable[1:]
        & (samples.segment[1:] == samples.segment[:-1])
        & (np.diff(samples.grid) == 1)
    )
    rows = np.flatnonzero(ok)
    starts = np.ones(rows.size, dtype=bool)
    starts[1:] = np.diff(rows) != 1
    return Transitions(
        obs=samples.obs[rows],
        command=samples.command[rows],
        next_obs=samples.obs[rows + 1],
        episode=np.cumsum(starts).astype(np.int64) - 1,
        stamps=samples.stamps[rows],
    )
