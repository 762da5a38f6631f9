"""Laps along a closed path: :class:`LapCounter`, shared by the closed loop and the Gymnasium environment."""

from __future__ import annotations

from rkmpc.track.path import Path
from rkmpc.track.projection import Projection

__all__ = ["LapCounter"]


class LapCounter:
    """Distance driven along a closed path (m), unwrapped across the start line, and lap crossings.

    Parameters
    ----------
    path : Path
        The closed path the laps are counted on.
    s0 : float
        Arc length of the start (m).
    """

    def __init__(self, path: Path, s0: float) -> None:
        self.path = path
        self.length = path.length
        self.s = s0
        #: Distance driven since the start (m), negative when driving backwards.
        self.distance = 0.0
        #: Times (s) at which the car completed each lap, interpolated within the step.
        self.crossings: list[float] = []

    def update(
        self, x: float, y: float, time: float, dt: float, *, first: bool = False
    ) -> tuple[Projection, float]:
        """Project the car at ``time`` (s), ``dt`` after the last update: the projection, the advance (m).

        ``first``: the start itself, which never completes a lap.
        """
        length = self.length
        proj = self.path.project(x, y, self.s)
        ds = (proj.s - self.s + 0.5 * length) % length - 0.5 * length
        goal = (len(self.crossings) + 1) * length
        if self.distance + ds >= goal and not first:
            # Interpolate the line-crossing time between the previous and this step.
            self.crossings.append(time - dt + dt * (goal - self.distance) / max(ds, 1e-12))
        self.distance += ds
        self.s = proj.s
        return proj, ds
