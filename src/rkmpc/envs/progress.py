"""A car's progress along a closed reference path, and the ``info`` an environment reports of it.

Shared by :class:`rkmpc.envs.f1tenth.F1TenthTrackEnv` and the F1TENTH gym's wrapper
:class:`rkmpc.envs.f1tenth_gym.TrackProgress`, so that a loop written for one reads the other's
``info`` the same way (``outcome``, ``completed_lap_times``, ``lateral_error``, ...).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rkmpc.core.angles import wrap_scalar
from rkmpc.track.path import Path, Projection

__all__ = ["PathProgress", "progress_info"]


class PathProgress:
    """Distance driven along a closed path (m), unwrapped across the start line, and lap crossings.

    Parameters
    ----------
    path : Path
        The reference path.
    s0 : float
        Arc length of the start (m).
    """

    def __init__(self, path: Path, s0: float) -> None:
        self.path = path
        self.s = s0
        self.distance = 0.0
        #: Times (s) at which the car completed each lap, interpolated within the step.
        self.crossings: list[float] = []

    def update(self, x: float, y: float, time: float, dt: float) -> tuple[Projection, float]:
        """Project the car at ``time`` (s), ``dt`` (s) after the last update.

        Returns the projection and the advance along the path since the last update (m).
        """
        length = self.path.length
        proj = self.path.project(x, y, self.s)
        ds = (proj.s - self.s + 0.5 * length) % length - 0.5 * length
        goal = (len(self.crossings) + 1) * length
        if self.distance + ds >= goal:
            self.crossings.append(time - dt + dt * (goal - self.distance) / max(ds, 1e-12))
        self.distance += ds
        self.s = proj.s
        return proj, ds

    @property
    def laps(self) -> int:
        """Laps completed."""
        return len(self.crossings)


def progress_info(
    time: float,
    yaw: float,
    progress: PathProgress,
    proj: Projection,
    margin: float,
    outcome: str,
    failure: str | None,
) -> dict[str, Any]:
    """What a step measured against the reference path (true state), for logs and tests.

    ``time`` (s), ``s`` (arc length, m), ``progress_laps``, ``lateral_error`` (m, left positive),
    ``heading_error`` (rad), ``track_margin`` (m, < 0 off the track), ``completed_lap_times`` (s),
    ``outcome`` (``"running"``, ``"max_laps"``, or how the episode ended) and ``failure`` (a
    message, or None).
    """
    return {
        "time": time,
        "s": proj.s,
        "progress_laps": progress.distance / progress.path.length,
        "lateral_error": proj.lateral,
        "heading_error": wrap_scalar(yaw - proj.heading) if math.isfinite(proj.heading) else math.nan,
        "track_margin": margin,
        "completed_lap_times": [float(t) for t in np.diff([0.0, *progress.crossings])],
        "outcome": outcome,
        "failure": failure,
    }
