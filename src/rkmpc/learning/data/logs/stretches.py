"""From a log's separate signals to transitions, through the bag import's resampler.

A *stretch* is a time interval in which every sensor (pose, speed, yaw rate) has no gap over
``max_gap`` and the pose has no jump. Inside one, the signals are merged into one odometry stream
on the union of their stamps (each interpolated linearly: the same values at the grid as
interpolating each signal on its own stamps) with an unmeasured lateral velocity, and resampled
onto the control period by :func:`rkmpc.learning.data.bags.resample.resample`, the commands held
``command_hold``. Each stretch's transitions are its own episodes: a gap or a jump always ends one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.learning.data.bags.read import ODOM_FIELDS, Stream
from rkmpc.learning.data.bags.resample import Transitions, resample, stretches, transitions

__all__ = ["Resampled", "cut", "intersect", "merged_stream", "resample_stretches", "sensor_stretches"]

Interval = tuple[int, int]
_NS = 1_000_000_000


def intersect(first: list[Interval], second: list[Interval]) -> list[Interval]:
    """The intervals (ns, closed) both sorted lists cover."""
    out: list[Interval] = []
    i = j = 0
    while i < len(first) and j < len(second):
        lo = max(first[i][0], second[j][0])
        hi = min(first[i][1], second[j][1])
        if lo <= hi:
            out.append((lo, hi))
        if first[i][1] < second[j][1]:
            i += 1
        else:
            j += 1
    return out


def sensor_stretches(sensors: list[Stream], gap_ns: int) -> list[Interval]:
    """The intervals (ns) in which every sensor has no gap over ``gap_ns``."""
    covered = stretches(sensors[0].stamps, gap_ns)
    for stream in sensors[1:]:
        covered = intersect(covered, stretches(stream.stamps, gap_ns))
    return covered


def cut(intervals: list[Interval], at: list[Interval]) -> list[Interval]:
    """``intervals`` with each ``(before, after)`` of ``at`` cut out (a jump from one pose to the next)."""
    out = list(intervals)
    for before, after in at:
        pieces: list[Interval] = []
        for lo, hi in out:
            if lo <= before and after <= hi:
                pieces += [(lo, before), (after, hi)]
            else:
                pieces.append((lo, hi))
        out = pieces
    return [(lo, hi) for lo, hi in out if lo < hi]


def merged_stream(pose: Stream, speed: Stream, yaw_rate: Stream | None, lo: int, hi: int) -> Stream:
    """Odometry (:data:`~rkmpc.learning.data.bags.read.ODOM_FIELDS`) of ``[lo, hi]`` (ns) from the sensors.

    ``vy`` is NaN (unmeasured), and ``yaw_rate`` when there is no yaw rate sensor.
    """
    parts = [pose.stamps, speed.stamps] + ([] if yaw_rate is None else [yaw_rate.stamps])
    every = np.unique(np.concatenate([[lo, hi], *parts]))
    stamps = every[(every >= lo) & (every <= hi)]
    at = (stamps - lo) / _NS

    def column(stream: Stream, j: int) -> np.ndarray:
        return np.interp(at, (stream.stamps - lo) / _NS, stream.values[:, j])

    rate = column(yaw_rate, 0) if yaw_rate is not None else np.full(len(stamps), math.nan)
    values = np.stack(
        [
            column(pose, 0),
            column(pose, 1),
            column(pose, 2),
            column(speed, 0),
            np.full(len(stamps), math.nan),
            rate,
        ],
        axis=1,
    )
    return Stream("merged", stamps, values, ODOM_FIELDS)


@dataclass(frozen=True, eq=False)
class Resampled:
    """The transitions of every stretch, episodes numbered across them, and what was left out.

    Parameters
    ----------
    found : Transitions
        The transitions (stamps in ns).
    reversing : int
        Grid samples left out because the speed was negative.
    stale : int
        Grid samples left out because no command was fresh.
    """

    found: Transitions
    reversing: int
    stale: int


def resample_stretches(
    intervals: list[Interval],
    pose: Stream,
    speed: Stream,
    yaw_rate: Stream | None,
    command: Stream,
    *,
    dt: float,
    hold: float,
    tolerance: float,
    lr: float,
) -> Resampled:
    """Resample each stretch (module docstring) and put the transitions together."""
    parts: list[Transitions] = []
    reversing = stale = 0
    for lo, hi in intervals:
        odom = merged_stream(pose, speed, yaw_rate, lo, hi)
        samples = resample(odom, command, None, dt=dt, gap=hold, tolerance=tolerance, lr=lr)
        negative = samples.obs[:, 3] < 0.0
        reversing += int(np.sum(negative))
        stale += int(np.sum(~samples.usable & ~negative))
        found = transitions(samples)
        if len(found):
            parts.append(found)
    return Resampled(found=_joined(parts), reversing=reversing, stale=stale)


def _joined(parts: list[Transitions]) -> Transitions:
    if not parts:
        empty = np.empty((0, 7))
        return Transitions(
            obs=empty, command=np.empty((0, 2)), next_obs=empty, episode=np.empty(0, np.int64),
            stamps=np.empty(0, np.int64),
        )  # fmt: skip
    offsets = np.cumsum([0] + [int(p.episode[-1]) + 1 for p in parts[:-1]])
    return Transitions(
        obs=np.concatenate([p.obs for p in parts]),
        command=np.concatenate([p.command for p in parts]),
        next_obs=np.concatenate([p.next_obs for p in parts]),
        episode=np.concatenate([p.episode + k for p, k in zip(parts, offsets, strict=True)]),
        stamps=np.concatenate([p.stamps for p in parts]),
    )
