"""The records a data-quality report is made of (:mod:`rkmpc.learning.data.quality.report`).

Times are seconds from the recording's start; all values in SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "Coverage",
    "EpisodeSpan",
    "Histogram",
    "PoseJump",
    "PosePoint",
    "Reversing",
    "ScaleFit",
    "SignalRate",
    "UnitCheck",
]


@dataclass(frozen=True, kw_only=True)
class SignalRate:
    """How often a signal came, and its gaps over ``gap_s`` (start: s from the start; length: s)."""

    signal: str
    source: str
    samples: int
    median_hz: float
    p5_hz: float
    p95_hz: float
    gap_s: float
    gaps: tuple[tuple[float, float], ...]

    @property
    def longest_gap_s(self) -> float:
        return max((g[1] for g in self.gaps), default=0.0)


@dataclass(frozen=True, kw_only=True)
class EpisodeSpan:
    """One episode: its first sample (s from the start), its length (s) and its transitions."""

    start_s: float
    duration_s: float
    transitions: int


@dataclass(frozen=True, kw_only=True)
class PoseJump:
    """A pose that moved (or turned) farther than the speed (or yaw rate) sensor allows.

    ``distance_m`` was moved in ``interval_s`` where the sensor allowed ``expected_m``;
    ``turn_rad`` is the heading change beyond what the yaw rate allowed (0 without one).
    """

    time_s: float
    interval_s: float
    distance_m: float
    expected_m: float
    turn_rad: float


@dataclass(frozen=True, kw_only=True)
class ScaleFit:
    """Speed sensor over the pose's speed: the median ratio over windows, with its quartiles.

    ``correlation`` is that of the sensor's distance with the pose's over the windows used.
    """

    factor: float
    q25: float
    q75: float
    correlation: float
    windows: int
    baseline_s: float
    warning: bool


@dataclass(frozen=True, kw_only=True)
class UnitCheck:
    """A measured rate against the same rate derived from the pose (by regression over windows).

    ``raw_factor`` is the column's raw value over the pose's rate (in SI); a column in its
    declared unit has ``raw_factor`` = 1 / (unit factor * scale). ``match`` is the unit the
    column looks like (None: none fits); ``suspicious`` when that is not the declared one.
    """

    signal: str
    column: str
    declared_unit: str
    raw_factor: float
    correlation: float
    windows: int
    match: str | None
    suspicious: bool
    message: str


@dataclass(frozen=True, kw_only=True)
class Reversing:
    """Stretches where the speed sensor read below ``-threshold_m_s``: excluded from the data."""

    segments: int
    total_s: float
    longest_s: float
    slowest_m_s: float
    threshold_m_s: float
    excluded_samples: int


@dataclass(frozen=True, kw_only=True)
class Histogram:
    """Counts in bins ``[edges[k], edges[k + 1])``; values beyond the edges count in the end bins."""

    edges: tuple[float, ...]
    counts: tuple[int, ...]


@dataclass(frozen=True, kw_only=True)
class Coverage:
    """Speeds (m/s) and curvatures (yaw rate / speed, 1/m, above 0.5 m/s) of the transitions."""

    speed_range: tuple[float, float]
    speed: Histogram
    curvature_range: tuple[float, float] | None
    curvature: Histogram | None


@dataclass(frozen=True, kw_only=True)
class PosePoint:
    """Where on the car the pose is, from how it moves sideways in turns.

    A car whose rear axle does not slide moves a point ``l`` ahead of that axle at the angle
    ``atan(l * curvature)`` to its heading; ``offset_m`` is ``l`` fitted by least squares (with
    its standard error ``std_error_m``) to the steps' direction errors (the angle between each
    step's displacement and its heading, :func:`rkmpc.learning.data.residuals.control_residuals`),
    beside a constant and a term in the lateral acceleration (real slip). ``expected_m`` is where
    the data should hold it (the centre of gravity, ``lr`` ahead of the rear axle; None: not
    known); ``consistent`` is None then.
    """

    offset_m: float
    std_error_m: float
    expected_m: float | None
    r2: float
    samples: int
    consistent: bool | None
