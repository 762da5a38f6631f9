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
from rkmpc.sim.laps import LapCounter
from rkmpc.track.path import Projection

__all__ = ["progress_info"]


def progress_info(
    time: float,
    yaw: float,
    progress: LapCounter,
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
