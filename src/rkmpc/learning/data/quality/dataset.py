"""The data-quality report of any transition data set (what training can print about its data).

A data set has no stamps and no raw signals: its samples are on the period, its episodes already
split at gaps. :func:`dataset_quality` measures what the transitions still show, with the rules of
:mod:`rkmpc.learning.data.quality.measures`: jumps (transitions whose pose moved farther than
their speed allows; found, not removed), the speed scale and the yaw rate's unit against the
pose, and the coverage. Times are seconds into the data set, its episodes laid end to end one
period apart.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from rkmpc.core.angles import wrap_angle
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.quality import measures as m
from rkmpc.learning.data.quality.report import QualityReport
from rkmpc.learning.data.quality.warnings import findings
from rkmpc.learning.data.units import UNITS

__all__ = ["dataset_quality"]


def dataset_quality(
    data: TransitionDataset, *, jump_distance: float = 0.3, jump_yaw: float = 0.3
) -> QualityReport:
    """The :class:`QualityReport` of ``data`` (module docstring).

    Parameters
    ----------
    data : TransitionDataset
        Any data set.
    jump_distance, jump_yaw : float
        The jump rule's margins (m, rad), as :class:`~rkmpc.learning.data.logs.CsvLogSpec`'s.
    """
    dt = data.dt
    series, speed, rate, start = _samples(data)
    fit = m.speed_scale(series, series.t, speed) if len(data) else None
    k = fit.factor if fit is not None else 1.0
    moved = np.hypot(*(data.next_obs[:, :2] - data.obs[:, :2]).T)
    turned = wrap_angle(data.next_obs[:, 2] - data.obs[:, 2])
    mean_speed = 0.5 * (data.obs[:, 3] + data.next_obs[:, 3])
    mean_rate = 0.5 * (data.obs[:, 4] + data.next_obs[:, 4])
    interval = np.full(len(data), dt)
    nan = math.nan
    measured = bool(len(data)) and bool(np.all(np.isfinite(rate)))
    factor, corr, windows = m.rate_fit(series, series.t, rate) if measured else (nan, nan, 0)
    jump, allowed, excess = m.jump_test(
        interval,
        moved,
        turned,
        mean_speed,
        mean_rate,
        scales=(k, factor),
        distance=jump_distance,
        turn=jump_yaw,
    )
    rows = np.flatnonzero(jump)
    units = [
        m.unit_check(
            signal="speed",
            column="obs.speed",
            declared="m/s",
            factor=fit.factor if fit else nan,
            correlation=fit.correlation if fit else nan,
            windows=fit.windows if fit else 0,
            units=UNITS["speed"],
        )
    ]
    if measured:
        units.append(
            m.unit_check(
                signal="yaw_rate",
                column="obs.yaw_rate",
                declared="rad/s",
                factor=factor,
                correlation=corr,
                windows=windows,
                units=UNITS["rate"],
            )
        )
    report = QualityReport(
        source=_source(data.metadata),
        raw=False,
        spec="transitions on the period (no stamps, no raw signals)",
        span_s=float(len(data) * dt),
        window=None,
        dt=dt,
        transitions=len(data),
        episodes=m.episode_spans(start, data.episode, dt),
        rates=(),
        max_gap_s=nan,
        jump_rule=(
            f"A transition whose pose moved more than {jump_distance:g} m farther than its speed "
            f"allows (mean speed * dt / {k:.3f}, the speed scale), or turned more than {jump_yaw:g} "
            "rad farther than its yaw rate allows, holds a jump (found here, not removed)."
        ),
        jumps=m.jumps_of(start[rows] + dt, interval[rows], moved[rows], allowed[rows], excess[rows]),
        jump_transitions=int(rows.size),
        speed_scale=fit,
        units=tuple(units),
        reversing=None,
        stale_command_samples=0,
        columns=(),
        coverage=m.coverage(data.obs[:, 3], data.obs[:, 4]),
        warnings=(),
    )
    return replace(report, warnings=findings(report))


def _source(metadata: dict[str, Any]) -> str:
    """Where the data came from: the log's folder, the bag, else the recorded source."""
    for key in ("log", "bag", "source"):
        if isinstance(metadata.get(key), str):
            return str(metadata[key])
    return "data set"


def _samples(data: TransitionDataset) -> tuple[m.PoseSeries, np.ndarray, np.ndarray, np.ndarray]:
    """Each episode's samples (its observations and the last next one), laid end to end.

    Returns the pose series, the speed and yaw rate of each sample, and each transition's start (s).
    """
    dt = data.dt
    t, xy, yaw, stretch, speed, rate = [], [], [], [], [], []
    start = np.zeros(len(data))
    offset = 0.0
    for k in np.unique(data.episode):
        rows = np.flatnonzero(data.episode == k)
        obs = np.concatenate([data.obs[rows], data.next_obs[rows[-1:]]])
        times = offset + dt * np.arange(len(obs))
        start[rows] = times[:-1]
        offset = float(times[-1]) + dt
        t.append(times)
        xy.append(obs[:, :2])
        yaw.append(np.unwrap(obs[:, 2]))
        stretch.append(np.full(len(obs), int(k)))
        speed.append(obs[:, 3])
        rate.append(obs[:, 4])
    if not t:
        empty = np.empty(0)
        series = m.PoseSeries(t=empty, xy=np.empty((0, 2)), yaw=empty, stretch=np.empty(0, np.int64))
        return series, empty, empty, start
    series = m.PoseSeries(
        t=np.concatenate(t), xy=np.concatenate(xy), yaw=np.concatenate(yaw), stretch=np.concatenate(stretch)
    )
    return series, np.concatenate(speed), np.concatenate(rate), start
