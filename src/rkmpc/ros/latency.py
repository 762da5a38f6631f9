"""Latency compensation: where the car will be when the next command acts.

An observation describes the car ``odometry`` seconds before it arrived, and a command acts
``actuation`` seconds after it is sent. Before the controller sees an observation,
:func:`propagate` moves its pose over that window with the paper's kinematic bicycle
(:func:`rkmpc.vehicle.kinematic.kinematic_step`): the wheel angle at each instant is the one
the car was commanded ``actuation`` seconds earlier (from :class:`CommandHistory`), the speed is
the measured one (it changes little over a few tens of milliseconds, and the speed loop lags
its set-point). ForzaETH's MPC propagates its state over its known latency the same way.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace

import numpy as np

from rkmpc.core.observation import Command, Observation
from rkmpc.vehicle.kinematic import kinematic_step

__all__ = ["CommandHistory", "propagate"]


class CommandHistory:
    """The commands sent, each with the instant it was sent (s, one clock for all).

    Parameters
    ----------
    keep : float
        How long commands are kept (s), beyond the newest.
    """

    def __init__(self, keep: float) -> None:
        self.keep = float(keep)
        self._sent: deque[tuple[float, Command]] = deque()

    def __len__(self) -> int:
        return len(self._sent)

    def add(self, time: float, command: Command) -> None:
        """Remember ``command`` sent at ``time`` (s); older ones beyond :attr:`keep` are dropped."""
        self._sent.append((float(time), command))
        while len(self._sent) > 1 and self._sent[1][0] < time - self.keep:
            self._sent.popleft()

    def active_at(self, time: float) -> Command | None:
        """The last command sent at or before ``time`` (s); None before the first."""
        found = None
        for sent, command in self._sent:
            if sent > time:
                break
            found = command
        return found

    def sent_between(self, start: float, end: float) -> list[float]:
        """Instants (s) strictly inside ``(start, end)`` at which a command was sent."""
        return [t for t, _ in self._sent if start < t < end]


def propagate(
    observation: Observation,
    history: CommandHistory,
    received: float,
    now: float,
    *,
    odometry: float,
    actuation: float,
    wheelbase: float,
) -> Observation:
    """The observation moved from when it was true to when the next command acts.

    Parameters
    ----------
    observation : Observation
        As received.
    history : CommandHistory
        The commands sent, on the clock of ``received`` and ``now``.
    received : float
        When the observation arrived (s); it was true ``odometry`` seconds before, its pose
        ``time - pose_time`` seconds earlier still (a late localiser's).
    now : float
        Now (s); the command computed now acts at ``now + actuation``.
    odometry, actuation : float
        Age of the odometry and delay of the actuators (s), >= 0.
    wheelbase : float
        Of the kinematic model (m).

    Returns
    -------
    Observation
        Pose and ``time`` at ``now + actuation``, ``pose_time`` NaN (the pose is as current as that
        time: a state estimator must not bring it forward again); the other fields as measured.
    """
    # A late localiser's pose is older than the rest of the odometry by its own latency.
    pose_age = observation.time - observation.pose_time if math.isfinite(observation.pose_time) else 0.0
    start = received - odometry - max(pose_age, 0.0)
    end = now + actuation
    if not end > start:
        return observation
    speed = observation.speed
    fallback = Command(speed, observation.steer_angle if math.isfinite(observation.steer_angle) else 0.0)
    state = np.array([observation.x, observation.y, observation.yaw], dtype=float)
    # The command acting at t was sent at t - actuation: the wheel angle changes where a send lands.
    cuts = [t + actuation for t in history.sent_between(start - actuation, end - actuation)]
    t = start
    for boundary in [*cuts, end]:
        if boundary <= t:
            continue
        acting = history.active_at(t - actuation) or fallback
        state = kinematic_step(state, (speed, acting.steer), wheelbase, boundary - t)
        t = boundary
    return replace(
        observation, x=float(state[0]), y=float(state[1]), yaw=float(state[2]), time=end, pose_time=math.nan
    )
