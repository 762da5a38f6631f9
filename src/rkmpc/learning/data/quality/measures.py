"""The measures of a data-quality report, on time-stamped signals (s) in SI units.

* **Rates.** Per signal: the median rate (1 / median interval) and the 5-95 % range of the
  intervals up to ``max_gap``; longer intervals are gaps, listed by start and length.
* **Windows.** The speed scale and the unit checks compare a sensor with the pose over windows of
  ``BASELINE_S`` (0.5 s) that start at every pose and stay inside one stretch (no gap, no jump):
  the distance the pose moved (chord) against the integral of the speed sensor, the heading
  change against the integral of the yaw rate. Over 0.5 s the particle filter's pose noise
  (0.1-0.2 m from one message to the next) is small next to the motion; a chord is shorter than
  the path by under 1 % at 5 m/s and 1.5 rad/s. The factor is the median of the windows' ratios
  (robust to the few bad windows), with its quartiles, from windows that moved at least
  ``MIN_DISTANCE_M`` (turned at least ``MIN_TURN_RAD``).
* **Jumps.** Between two poses at most ``max_gap`` apart: the pose moved ``d`` where the speed
  sensor allowed ``e = |v| dt / k`` (``k`` the speed scale), and turned ``dyaw`` where the yaw
  rate allowed ``r dt``; ``d - e > distance`` or ``|dyaw - r dt| > turn`` is a jump.
* **Reversing.** Runs of the speed sensor below ``-REVERSE_THRESHOLD`` m/s.
* **Coverage.** Histograms of the transitions' speeds (0.5 m/s bins) and curvatures (yaw rate /
  speed above 0.5 m/s, 0.25 1/m bins, clipped to +-3 1/m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.learning.data.quality.records import (
    Coverage,
    EpisodeSpan,
    Histogram,
    PoseJump,
    Reversing,
    ScaleFit,
    SignalRate,
    UnitCheck,
)

__all__ = [
    "BASELINE_S",
    "SPEED_SCALE_TOLERANCE",
    "UNIT_TOLERANCE",
    "PoseSeries",
    "coverage",
    "episode_spans",
    "jump_test",
    "jumps_of",
    "rate_fit",
    "reversing",
    "signal_rate",
    "speed_scale",
    "unit_check",
]

#: Length (s) of the windows over which sensors are compared with the pose.
BASELINE_S = 0.5
#: A speed scale further than this from 1 is a warning.
SPEED_SCALE_TOLERANCE = 0.1
#: A factor within this (relative) of a unit's matches that unit.
UNIT_TOLERANCE = 0.15
MIN_DISTANCE_M = 0.25
MIN_TURN_RAD = 0.15
MIN_WINDOWS = 10
REVERSE_THRESHOLD = 0.05
_POINTS = 11  # samples of a sensor over a window (its integral by the mean)
_CURVATURE_SPEED = 0.5
_CURVATURE_LIMIT = 3.0
#: Factors with names (a unit's mix-up), for the messages.
_NAMED = {180.0 / math.pi: "180/pi", math.pi / 180.0: "pi/180", 3.6: "3.6", 1 / 3.6: "1/3.6", -1.0: "-1"}


@dataclass(frozen=True, eq=False)
class PoseSeries:
    """Poses in stretches (between gaps and jumps); comparison windows never leave a stretch.

    Parameters
    ----------
    t : numpy.ndarray, shape (N,)
        Time (s), increasing.
    xy : numpy.ndarray, shape (N, 2)
        Position (m).
    yaw : numpy.ndarray, shape (N,)
        Heading (rad), continuous (unwrapped).
    stretch : numpy.ndarray, shape (N,)
        Stretch of each pose, non-decreasing.
    """

    t: np.ndarray
    xy: np.ndarray
    yaw: np.ndarray
    stretch: np.ndarray

    def windows(self, baseline: float) -> tuple[np.ndarray, np.ndarray]:
        """Poses that start a window inside their stretch, and each window's end time (s)."""
        last = np.zeros(len(self.t))
        ends = np.flatnonzero(np.diff(self.stretch) != 0)
        bounds = np.concatenate([[-1], ends, [len(self.t) - 1]])
        for lo, hi in zip(bounds[:-1] + 1, bounds[1:], strict=True):
            last[lo : hi + 1] = self.t[hi]
        start = np.flatnonzero(self.t + baseline <= last + 1e-9)
        return start, self.t[start] + baseline


def _integral(t: np.ndarray, v: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """``v``'s integral over each ``[t0, t1]`` (mean of ``_POINTS`` interpolated samples)."""
    share = np.linspace(0.0, 1.0, _POINTS)
    at = t0[:, None] + share[None, :] * (t1 - t0)[:, None]
    return np.interp(at, t, v).mean(axis=1) * (t1 - t0)


def signal_rate(signal: str, source: str, t: np.ndarray, max_gap: float) -> SignalRate:
    """How often ``t`` (s) came, and its gaps over ``max_gap`` (s)."""
    step = np.diff(t)
    regular = step[step <= max_gap]
    gaps = tuple((float(t[k]), float(step[k])) for k in np.flatnonzero(step > max_gap))
    if regular.size == 0:
        nothing = {"median_hz": 0.0, "p5_hz": 0.0, "p95_hz": 0.0}
        return SignalRate(signal=signal, source=source, samples=len(t), gap_s=max_gap, gaps=gaps, **nothing)
    slow, fast = np.percentile(regular, [95, 5])
    return SignalRate(
        signal=signal,
        source=source,
        samples=len(t),
        median_hz=float(1.0 / np.median(regular)),
        p5_hz=float(1.0 / slow),
        p95_hz=float(1.0 / fast),
        gap_s=max_gap,
        gaps=gaps,
    )


def speed_scale(
    pose: PoseSeries, t: np.ndarray, speed: np.ndarray, baseline: float = BASELINE_S
) -> ScaleFit | None:
    """Speed sensor over the pose's speed (module docstring); None with too few windows."""
    start, end = pose.windows(baseline)
    if start.size == 0:
        return None
    t0 = pose.t[start]
    moved = np.hypot(*(np.stack([np.interp(end, pose.t, c) for c in pose.xy.T]) - pose.xy[start].T))
    measured = _integral(t, speed, t0, end)
    slowest = np.min(np.interp(t0[:, None] + np.linspace(0, baseline, _POINTS), t, speed), axis=1)
    use = (moved >= MIN_DISTANCE_M) & (slowest > 0.0)
    if int(use.sum()) < MIN_WINDOWS:
        return None
    ratio = measured[use] / moved[use]
    q25, factor, q75 = (float(q) for q in np.percentile(ratio, [25, 50, 75]))
    return ScaleFit(
        factor=factor,
        q25=q25,
        q75=q75,
        correlation=float(np.corrcoef(measured[use], moved[use])[0, 1]),
        windows=int(use.sum()),
        baseline_s=baseline,
        warning=abs(factor - 1.0) > SPEED_SCALE_TOLERANCE,
    )


def rate_fit(
    pose: PoseSeries, t: np.ndarray, rate: np.ndarray, baseline: float = BASELINE_S
) -> tuple[float, float, int]:
    """``(factor, correlation, windows)``: a yaw rate (rad/s) over the pose's (module docstring).

    The factor is NaN with fewer than ``MIN_WINDOWS`` windows that turned ``MIN_TURN_RAD``; the
    correlation is over every window.
    """
    start, end = pose.windows(baseline)
    if start.size < 2:
        return math.nan, math.nan, 0
    turned = np.interp(end, pose.t, pose.yaw) - pose.yaw[start]
    measured = _integral(t, rate, pose.t[start], end)
    use = np.abs(turned) >= MIN_TURN_RAD
    spread = np.std(turned) * np.std(measured)
    corr = (
        float(np.mean((turned - turned.mean()) * (measured - measured.mean())) / spread)
        if spread
        else math.nan
    )
    if int(use.sum()) < MIN_WINDOWS:
        return math.nan, corr, int(use.sum())
    return float(np.median(measured[use] / turned[use])), corr, int(use.sum())


def _named(factor: float) -> str:
    for value, name in _NAMED.items():
        if abs(factor / value - 1.0) < UNIT_TOLERANCE:
            return f"{factor:.3g} (about {name} = {value:.3g})"
    return f"{factor:.3g}"


def unit_check(
    *,
    signal: str,
    column: str,
    declared: str,
    factor: float,
    correlation: float,
    windows: int,
    units: dict[str, float],
    column_scale: float = 1.0,
) -> UnitCheck:
    """Which of ``units`` (name: SI factor) the column is in, from ``factor`` = its SI value / the pose's.

    ``column_scale`` is the spec's extra factor of the column; the declared unit's SI factor times
    it turned the raw column into the SI value the fit saw.
    """
    si = units[declared] * column_scale
    raw = factor / si
    what = f"{signal} ({column}, declared {declared})"
    if not math.isfinite(raw):
        message = f"{what}: too few windows ({windows}) to check it against the pose."
        return UnitCheck(
            signal=signal, column=column, declared_unit=declared, raw_factor=raw, correlation=correlation,
            windows=windows, match=None, suspicious=False, message=message,
        )  # fmt: skip
    match = next((u for u, c in units.items() if abs(raw * c * column_scale - 1.0) < UNIT_TOLERANCE), None)
    flipped = next((u for u, c in units.items() if abs(raw * c * column_scale + 1.0) < UNIT_TOLERANCE), None)
    fit = f"correlation {correlation:.2f} over {windows} windows"
    if match == declared:
        message = f"{what} matches the pose: SI value / pose = {factor:.3f} ({fit})."
    elif match is not None:
        message = (
            f"{what} matches the pose only after a factor {_named(factor)}: the column looks like "
            f"{match}, not {declared} ({fit})."
        )
    elif flipped is not None:
        match = f"-{flipped}"
        message = f"{what} matches the pose with its sign flipped (factor {_named(factor)}; {fit})."
    else:
        message = f"{what} matches no unit: SI value / pose = {_named(factor)} ({fit})."
    return UnitCheck(
        signal=signal, column=column, declared_unit=declared, raw_factor=raw, correlation=correlation,
        windows=windows, match=match, suspicious=match != declared, message=message,
    )  # fmt: skip


def jump_test(
    interval: np.ndarray,
    moved: np.ndarray,
    turned: np.ndarray,
    speed: np.ndarray,
    yaw_rate: np.ndarray,
    *,
    scales: tuple[float, float],
    distance: float,
    turn: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(jump, allowed distance (m), excess turn (rad))`` of pose steps (module docstring).

    ``moved`` (m) and ``turned`` (rad) in ``interval`` (s), with the sensors' ``speed`` (m/s) and
    ``yaw_rate`` (rad/s; NaN: not measured, taken as 0) over it. ``scales`` are the speed's and
    the yaw rate's factors over the pose's (a fit, or 1): the sensors are divided by them, so a
    sensor with a wrong scale or unit still tells a jump from motion.
    """
    speed_scale, rate_scale = (f if math.isfinite(f) and abs(f) > 1e-2 else 1.0 for f in scales)
    allowed = np.abs(speed) * interval / abs(speed_scale)
    excess = np.abs(turned - np.nan_to_num(yaw_rate) / rate_scale * interval)
    return (moved - allowed > distance) | (excess > turn), allowed, excess


def jumps_of(
    t: np.ndarray, interval: np.ndarray, moved: np.ndarray, allowed: np.ndarray, excess: np.ndarray
) -> tuple[PoseJump, ...]:
    """The jump records (``t``: the time of the pose after each jump, s)."""
    return tuple(
        PoseJump(
            time_s=float(a), interval_s=float(b), distance_m=float(c), expected_m=float(d), turn_rad=float(e)
        )
        for a, b, c, d, e in zip(t, interval, moved, allowed, excess, strict=True)
    )


def reversing(
    t: np.ndarray, speed: np.ndarray, excluded: int, threshold: float = REVERSE_THRESHOLD
) -> Reversing:
    """Runs of ``speed`` (m/s) below ``-threshold``; ``excluded`` grid samples the import left out."""
    below = np.concatenate([[False], speed < -threshold, [False]])
    edges = np.flatnonzero(np.diff(below.astype(np.int8)))
    runs = edges.reshape(-1, 2)
    lengths = [float(t[min(b, len(t) - 1)] - t[a]) for a, b in runs]
    return Reversing(
        segments=len(runs),
        total_s=float(sum(lengths)),
        longest_s=max(lengths, default=0.0),
        slowest_m_s=float(np.min(speed)) if len(runs) else 0.0,
        threshold_m_s=threshold,
        excluded_samples=excluded,
    )


def _histogram(values: np.ndarray, lo: float, hi: float, step: float) -> Histogram:
    edges = np.arange(lo, hi + 0.5 * step, step)
    if edges.size < 2:
        edges = np.array([lo, lo + step])
    counts, _ = np.histogram(np.clip(values, edges[0], edges[-1]), bins=edges)
    return Histogram(edges=tuple(float(e) for e in edges), counts=tuple(int(c) for c in counts))


def coverage(speed: np.ndarray, yaw_rate: np.ndarray) -> Coverage:
    """Speeds (m/s) and curvatures (1/m) of transitions (module docstring)."""
    if speed.size == 0:
        empty = Histogram(edges=(0.0, 0.5), counts=(0,))
        return Coverage(speed_range=(0.0, 0.0), speed=empty, curvature_range=None, curvature=None)
    top = max(0.5, math.ceil(float(np.max(speed)) / 0.5) * 0.5)
    fast = (speed >= _CURVATURE_SPEED) & np.isfinite(yaw_rate)
    speeds = _histogram(speed, 0.0, top, 0.5)
    if not np.any(fast):
        return Coverage(
            speed_range=(float(speed.min()), float(speed.max())),
            speed=speeds,
            curvature_range=None,
            curvature=None,
        )
    kappa = yaw_rate[fast] / speed[fast]
    limit = min(_CURVATURE_LIMIT, max(0.25, math.ceil(float(np.max(np.abs(kappa))) / 0.25) * 0.25))
    return Coverage(
        speed_range=(float(speed.min()), float(speed.max())),
        speed=speeds,
        curvature_range=(float(kappa.min()), float(kappa.max())),
        curvature=_histogram(kappa, -limit, limit, 0.25),
    )


def episode_spans(start: np.ndarray, episode: np.ndarray, dt: float) -> tuple[EpisodeSpan, ...]:
    """Each episode's first sample (s), length (s) and transitions, from each transition's start (s)."""
    spans = []
    for k in np.unique(episode):
        rows = np.flatnonzero(episode == k)
        spans.append(
            EpisodeSpan(
                start_s=float(start[rows[0]]), duration_s=float(len(rows) * dt), transitions=len(rows)
            )
        )
    return tuple(spans)
