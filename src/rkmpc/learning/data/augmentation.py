"""Local-frame windows: the data augmentation of the paper's Sec. IV-A.

Fu et al., *Residual Koopman Model Predictive Control for Enhanced Vehicle
Dynamics with Small On-Track Data Input*, Sec. IV-A ("Data Collection and
Preprocessing"), re-express short stretches of the recorded trajectory in the
body frame of a randomly chosen sample. Every stretch then starts at the
origin with zero heading, so the kinematic model is always linearised about
the same heading, and positions stay small (no normalisation needed).

Here a *window* is ``n_points`` consecutive transitions of one episode; its
*origin* is the pose of the window's first observation. A fraction ``ratio``
of the samples that can start a full window are drawn (without replacement)
as origins, so ``N`` raw transitions give about ``N * ratio * n_points``
local-frame transitions. Windows may overlap; each is transformed
independently. See ``docs/method.md`` for the choices made where the paper is
not explicit.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from rkmpc.core.angles import wrap_angle
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer
from rkmpc.learning.data.dataset import TransitionDataset


@dataclass(frozen=True)
class AugmentConfig:
    """Settings of the local-frame augmentation.

    Parameters
    ----------
    ratio : float
        Conversion ratio, ``0 < ratio <= 1``: the fraction of the samples that
        can start a full window which become window origins.
    n_points : int
        ``N_p``, consecutive transitions per window (>= 1); the paper asks for
        slightly more than the MPC horizon (30 steps here).
    seed : int
        Seed (>= 0) of :func:`numpy.random.default_rng` that draws the origins.
    """

    ratio: float = 0.3
    n_points: int = 35
    seed: int = 0

    def __post_init__(self) -> None:
        if not (isinstance(self.ratio, numbers.Real) and math.isfinite(self.ratio) and 0 < self.ratio <= 1):
            raise ParameterError(f"AugmentConfig.ratio must be in (0, 1], got {self.ratio!r}")
        if not is_integer(self.n_points):
            raise ParameterError(f"AugmentConfig.n_points must be an integer, got {self.n_points!r}")
        if self.n_points < 1:
            raise ParameterError(f"AugmentConfig.n_points must be >= 1, got {self.n_points!r}")
        if not is_integer(self.seed, 0):
            raise ParameterError(f"AugmentConfig.seed must be an integer >= 0, got {self.seed!r}")


def to_local_frame(poses: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Express poses in the frame of ``origin``.

    The frame's origin is at ``(x0, y0)`` and its first axis points along
    ``yaw0``: positions are translated by ``-(x0, y0)`` and then rotated by
    ``-yaw0``; headings become ``yaw - yaw0`` wrapped to ``(-pi, pi]``.

    Parameters
    ----------
    poses : numpy.ndarray, shape (..., 3)
        ``[x, y, yaw]`` (m, m, rad) in the global frame.
    origin : numpy.ndarray, shape (3,) or broadcastable to ``poses``
        ``[x0, y0, yaw0]`` (m, m, rad) of the local frame.

    Returns
    -------
    numpy.ndarray, shape of ``poses``
        ``[x, y, yaw]`` in the local frame.
    """
    p = np.asarray(poses, dtype=float)
    o = np.asarray(origin, dtype=float)
    if p.shape[-1:] != (3,) or o.shape[-1:] != (3,):
        raise ValueError(f"poses and origin must end in a dimension of 3, got {p.shape} and {o.shape}")
    dx = p[..., 0] - o[..., 0]
    dy = p[..., 1] - o[..., 1]
    cos0 = np.cos(o[..., 2])
    sin0 = np.sin(o[..., 2])
    out = np.empty(np.broadcast_shapes(p.shape, o.shape))
    out[..., 0] = cos0 * dx + sin0 * dy
    out[..., 1] = -sin0 * dx + cos0 * dy
    out[..., 2] = wrap_angle(p[..., 2] - o[..., 2])
    return out


@dataclass(frozen=True, eq=False)
class LocalWindows:
    """Windows of consecutive transitions, each in the frame of its first pose.

    Parameters
    ----------
    obs : numpy.ndarray, shape (M, n_points, 7)
        Observations; ``x, y, yaw`` in the window's frame (so
        ``obs[:, 0, :3] == 0``), yaw continuous along the window (not wrapped),
        the other columns as recorded (they do not depend on the frame).
    command : numpy.ndarray, shape (M, n_points, 2)
        Applied commands ``[speed (m/s), steer (rad)]``.
    next_obs : numpy.ndarray, shape (M, n_points, 7)
        Observations after each step, in the same frame as ``obs``.
    origin_index : numpy.ndarray, shape (M,)
        Data-set index of each window's first transition, increasing.
    raw_count : int
        ``N``, the number of transitions of the source data set.
    """

    obs: np.ndarray
    command: np.ndarray
    next_obs: np.ndarray
    origin_index: np.ndarray
    raw_count: int

    @property
    def n_windows(self) -> int:
        """``M``, the number of windows."""
        return int(self.obs.shape[0])

    @property
    def n_points(self) -> int:
        """``N_p``, transitions per window."""
        return int(self.obs.shape[1])

    @property
    def augmented_count(self) -> int:
        """Local-frame transitions in all, ``M * n_points``."""
        return self.n_windows * self.n_points

    @property
    def indices(self) -> np.ndarray:
        """Data-set index of every window transition, shape (M, n_points).

        Use it to gather per-transition labels computed on the source data
        set, e.g. ``labels.delta[windows.indices]`` (control residuals do not
        depend on the frame).
        """
        return self.origin_index[:, None] + np.arange(self.n_points)[None, :]

    def flatten(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(obs, command, next_obs)`` with windows stacked, shapes (M * n_points, 7 | 2 | 7)."""
        return (
            self.obs.reshape(-1, self.obs.shape[-1]),
            self.command.reshape(-1, self.command.shape[-1]),
            self.next_obs.reshape(-1, self.next_obs.shape[-1]),
        )


def valid_origins(data: TransitionDataset, n_points: int) -> np.ndarray:
    """Indices that can start a window of ``n_points`` transitions inside one episode.

    Parameters
    ----------
    data : TransitionDataset
        Source transitions.
    n_points : int
        Window length (>= 1).

    Returns
    -------
    numpy.ndarray, shape (K,), int64
        Every ``i`` with ``i + n_points <= N`` and
        ``episode[i + n_points - 1] == episode[i]``.
    """
    n = len(data)
    if n_points < 1 or n < n_points:
        return np.empty(0, dtype=np.int64)
    start = np.arange(n - n_points + 1, dtype=np.int64)
    same = data.episode[start] == data.episode[start + n_points - 1]
    return start[same]


def local_frame_windows(data: TransitionDataset, config: AugmentConfig | None = None) -> LocalWindows:
    """Cut seeded windows from a data set and move each into its own local frame.

    ``M = max(1, round(ratio * K))`` origins are drawn without replacement
    among the ``K`` valid origins (:func:`valid_origins`) with
    ``numpy.random.default_rng(seed)`` and sorted. Window ``m`` holds the
    transitions ``origin_index[m] .. origin_index[m] + n_points - 1``. Its
    poses (of ``obs`` and ``next_obs``) are expressed in the frame of
    ``obs[origin_index[m], :3]`` by :func:`to_local_frame`; headings are then
    made continuous: each one is the origin-relative heading of the previous
    sample plus the wrapped heading change, so a window that crosses
    ``yaw = +-pi`` has no jump.

    Parameters
    ----------
    data : TransitionDataset
        Source transitions.
    config : AugmentConfig, optional
        Ratio, window length and seed; defaults to ``AugmentConfig()``.

    Returns
    -------
    LocalWindows

    Raises
    ------
    ParameterError
        When no episode holds ``n_points`` transitions.
    """
    cfg = config if config is not None else AugmentConfig()
    n_p = int(cfg.n_points)
    candidates = valid_origins(data, n_p)
    if candidates.size == 0:
        raise ParameterError(
            f"local_frame_windows: no episode holds n_points = {n_p} consecutive transitions "
            f"(data set has {len(data)} transitions)"
        )
    m = max(1, round(cfg.ratio * candidates.size))
    rng = np.random.default_rng(cfg.seed)
    origins = np.sort(rng.choice(candidates, size=m, replace=False)).astype(np.int64)
    idx = origins[:, None] + np.arange(n_p)[None, :]  # (M, n_p)

    obs = data.obs[idx].copy()  # (M, n_p, 7)
    next_obs = data.next_obs[idx].copy()
    command = data.command[idx].copy()
    origin_pose = data.obs[origins, :3][:, None, :]  # (M, 1, 3)
    obs[..., :3] = to_local_frame(obs[..., :3], origin_pose)
    next_obs[..., :3] = to_local_frame(next_obs[..., :3], origin_pose)
    # Continuous headings relative to the origin: accumulate wrapped changes.
    yaw = data.obs[idx, 2]
    rel = np.zeros_like(yaw)
    rel[:, 1:] = np.cumsum(wrap_angle(np.diff(yaw, axis=1)), axis=1)
    obs[..., 2] = rel
    next_obs[..., 2] = rel + wrap_angle(data.next_obs[idx, 2] - yaw)
    return LocalWindows(
        obs=obs,
        command=command,
        next_obs=next_obs,
        origin_index=origins,
        raw_count=len(data),
    )
