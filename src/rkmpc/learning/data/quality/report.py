"""The data-quality report of a recording or a data set: typed, frozen, as JSON and as Markdown.

A :class:`QualityReport` says what an import found in what a car measured: the rate of each
signal and its gaps, the episodes the gaps (and the rest) left, the pose jumps taken out, the
scale between the speed sensor and the speed of the pose, units that do not match what they
claim, reversing, columns that carry nothing, and the speeds and curvatures the data cover.
Times are seconds from the recording's start. The measures are in
:mod:`rkmpc.learning.data.quality.measures`.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, fields
from typing import Any

from rkmpc.core.jsonutil import to_json_ready
from rkmpc.learning.data.quality.records import (
    Coverage,
    EpisodeSpan,
    Histogram,
    PoseJump,
    PosePoint,
    Reversing,
    ScaleFit,
    SignalRate,
    UnitCheck,
)
from rkmpc.learning.data.quality.speed_command import SpeedCommandCheck

__all__ = ["QualityReport"]

_WIDTH = 100
_LISTED = 8  # rows of a long list shown in the Markdown (all of them are in the JSON)


@dataclass(frozen=True, kw_only=True)
class QualityReport:
    """What an import found in a recording (or what a data set shows).

    Parameters
    ----------
    source : str
        The recording (folder, bag) or ``"data set"``.
    raw : bool
        True: made at import from the raw signals (jumps, reversing and stale commands removed);
        False: from a data set's transitions (jumps found, not removed; no rates, no reversing).
    spec : str
        The layout or the import (``friction-maps``, a spec file, ``bag``, ``dataset``).
    span_s : float
        Length of the recording (s) inside the window.
    window : str or None
        The window (``START:END``), None: all of it.
    dt : float
        Control period (s).
    transitions : int
        Transitions of the data set.
    episodes : tuple of EpisodeSpan
        Its episodes.
    rates : tuple of SignalRate
        Per signal (empty for a data set: its samples are on the grid).
    max_gap_s : float
        A gap longer than this ends an episode.
    jump_rule : str
        How jumps are found and what happens to them.
    jumps : tuple of PoseJump
        The jumps found.
    jump_transitions : int
        Transitions removed because of jumps (a data set's: transitions that hold one).
    speed_scale : ScaleFit or None
        None when too few windows moved far enough.
    units : tuple of UnitCheck
        Checks of measured rates against the pose.
    reversing : Reversing or None
        None for a data set (its speeds are >= 0).
    stale_command_samples : int
        Grid samples left out because no command was fresh.
    columns : tuple of (str, str)
        ``(file, note)``: columns constant in every row or repeating another.
    coverage : Coverage
        Speeds and curvatures of the transitions.
    speed_command : SpeedCommandCheck or None
        Whether the recorded speed command set the car's speed (and whether it was replaced).
    pose_point : PosePoint or None
        Where on the car the pose is, from its sideways motion in turns (None: not measured).
    warnings : tuple of str
        The findings that need a look, in words.
    """

    source: str
    raw: bool
    spec: str
    span_s: float
    window: str | None
    dt: float
    transitions: int
    episodes: tuple[EpisodeSpan, ...]
    rates: tuple[SignalRate, ...]
    max_gap_s: float
    jump_rule: str
    jumps: tuple[PoseJump, ...]
    jump_transitions: int
    speed_scale: ScaleFit | None
    units: tuple[UnitCheck, ...]
    reversing: Reversing | None
    stale_command_samples: int
    columns: tuple[tuple[str, str], ...]
    coverage: Coverage
    warnings: tuple[str, ...]
    speed_command: SpeedCommandCheck | None = None
    pose_point: PosePoint | None = None

    def to_json(self) -> dict[str, Any]:
        """Plain JSON types (NaN as null); ``longest_gap_s`` added to each rate."""
        record = {f.name: to_json_ready(getattr(self, f.name)) for f in fields(self)}
        for rate, out in zip(self.rates, record["rates"], strict=True):
            out["longest_gap_s"] = rate.longest_gap_s
        return dict(record)

    def to_markdown(self) -> str:
        """The report as Markdown, no line over 100 characters."""
        parts = [
            _header(self),
            _rates(self),
            _jumps(self),
            _speed_scale(self),
            _units(self),
            _pose_point(self.pose_point),
            _reversing(self),
            _columns(self),
            _coverage(self.coverage),
            _warnings(self),
        ]
        lines = [line for part in parts for line in [*part, ""]]
        return "\n".join(lines).rstrip() + "\n"


def _wrap(text: str, indent: str = "") -> list[str]:
    """``text`` in lines of at most 100 characters (continuation lines indented by ``indent``)."""
    return textwrap.wrap(text, _WIDTH, subsequent_indent=indent, break_on_hyphens=False) or [""]


def _short(name: str, width: int = 32) -> str:
    """``name``, cut in the middle to ``width`` characters (a table row stays under 100)."""
    return name if len(name) <= width else name[: width // 2 - 1] + "..." + name[-(width // 2 - 2) :]


def _header(report: QualityReport) -> list[str]:
    window = f" (window {report.window})" if report.window else ""
    lines = [f"## Data quality: {report.source}", ""]
    counts = f"{report.transitions} transitions in {len(report.episodes)} episode(s) at dt = {report.dt:g} s"
    if report.raw:
        text = (
            f"Import: {report.spec}. {report.span_s:.1f} s of recording{window}; {counts}. An episode "
            f"ends at a gap over {report.max_gap_s:g} s, a pose jump, reversing or a stale command "
            f"({report.stale_command_samples} grid sample(s) without a fresh command)."
        )
    else:
        text = f"From a data set: {report.spec}. {counts}, {report.span_s:.1f} s."
    lines += _wrap(text)
    spans = [f"{e.start_s:.2f} ({e.duration_s:.2f}, {e.transitions})" for e in report.episodes]
    more = f", ... ({len(spans) - _LISTED} more)" if len(spans) > _LISTED else ""
    if spans:
        lines += _wrap("Episodes, start s (length s, transitions): " + ", ".join(spans[:_LISTED]) + more)
    return lines


def _rates(report: QualityReport) -> list[str]:
    lines = ["### Sample rates and gaps"]
    if not report.rates:
        return [*lines, "", "None measured: a data set's samples are on its period."]
    lines += [
        "",
        "| signal | source | samples | median Hz | 5-95 % Hz | gaps (over s) | longest s |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in report.rates:
        lines.append(
            f"| {r.signal} | {_short(r.source)} | {r.samples} | {r.median_hz:.1f} "
            f"| {r.p5_hz:.1f}-{r.p95_hz:.1f} | {len(r.gaps)} (> {r.gap_s:g}) | {r.longest_gap_s:.2f} |"
        )
    gaps = [
        f"{r.signal} " + ", ".join(f"{start:.2f} ({length:.2f})" for start, length in r.gaps[:_LISTED])
        for r in report.rates
        if r.gaps
    ]
    if gaps:
        lines += ["", *_wrap("Gaps, start s (length s): " + "; ".join(gaps) + ".")]
    return lines


def _jumps(report: QualityReport) -> list[str]:
    lines = ["### Pose jumps (outliers, not labels)", "", *_wrap(report.jump_rule), ""]
    if not report.jumps:
        return [*lines, "No jumps found."]
    big = sorted(report.jumps, key=lambda j: j.distance_m - j.expected_m, reverse=True)
    verb = "removed" if report.raw else "holding one (kept)"
    lines += _wrap(
        f"{len(report.jumps)} jump(s); {report.jump_transitions} transition(s) {verb}. Largest first:"
    )
    lines += ["", "| time s | interval s | moved m | allowed m | turn rad |", "|---:|---:|---:|---:|---:|"]
    for j in big[:_LISTED]:
        lines.append(
            f"| {j.time_s:.2f} | {j.interval_s:.3f} | {j.distance_m:.3f} | {j.expected_m:.3f} "
            f"| {j.turn_rad:.3f} |"
        )
    return lines


def _speed_scale(report: QualityReport) -> list[str]:
    fit = report.speed_scale
    lines = ["### Speed scale", ""]
    if fit is None:
        return [*lines, "Not measured: too few windows in which the car moved far enough."]
    lines += _wrap(
        f"Speed sensor / speed of the pose = {fit.factor:.3f} (median of {fit.windows} windows of "
        f"{fit.baseline_s:g} s; quartiles {fit.q25:.3f}-{fit.q75:.3f})"
        + (": far from 1, check the sensor's scale." if fit.warning else ".")
    )
    check = report.speed_command
    if check is not None and check.samples:
        text = (
            f"Speed reached / speed commanded = {check.ratio:.2f} (median of {check.samples} transitions)"
            + ("." if check.tracks else ": the command did not set the speed.")
            + (" The speed command is replaced by the measured speed." if check.replaced else "")
        )
        lines += ["", *_wrap(text)]
    return lines


def _units(report: QualityReport) -> list[str]:
    lines = ["### Units", ""]
    if not report.units:
        return [*lines, "No rate to check against the pose."]
    return lines + [line for u in report.units for line in _wrap(f"- {u.message}", "  ")]


def _pose_point(point: PosePoint | None) -> list[str]:
    lines = ["### Where the pose is on the car", ""]
    if point is None:
        return [*lines, "Not measured: too few steps above 0.5 m/s, or too little turning."]
    text = (
        f"The pose moves like a point {point.offset_m:.3f} +- {point.std_error_m:.3f} m ahead of a rear "
        f"axle that does not slide (fit of the steps' sideways motion on their curvature, "
        f"{point.samples} steps, R^2 {point.r2:.2f})"
    )
    if point.expected_m is None:
        return lines + _wrap(text + ".")
    verdict = "consistent" if point.consistent else "NOT consistent"
    return lines + _wrap(
        f"{text}; the data should hold the centre of gravity, {point.expected_m:.3f} m ahead: {verdict}."
    )


def _reversing(report: QualityReport) -> list[str]:
    r = report.reversing
    lines = ["### Reversing (excluded)", ""]
    if r is None:
        return [*lines, "Not known: a data set holds no negative speed."]
    if r.segments == 0:
        return [*lines, f"None (the speed never read below -{r.threshold_m_s:g} m/s)."]
    return lines + _wrap(
        f"{r.segments} segment(s), {r.total_s:.2f} s in all, the longest {r.longest_s:.2f} s, down to "
        f"{r.slowest_m_s:.2f} m/s (below -{r.threshold_m_s:g} m/s); {r.excluded_samples} grid "
        "sample(s) with a negative speed left out."
    )


def _columns(report: QualityReport) -> list[str]:
    if not report.columns:
        return ["### Columns that carry nothing", "", "None."]
    lines = ["### Columns that carry nothing", ""]
    return lines + [line for file, note in report.columns for line in _wrap(f"- {file}: {note}", "  ")]


def _histogram(h: Histogram, unit: str) -> str:
    bins = [f"{lo:g} to {hi:g}: {n}" for lo, hi, n in zip(h.edges[:-1], h.edges[1:], h.counts, strict=True)]
    return f"transitions per bin ({unit}): " + ", ".join(bins) + "."


def _coverage(c: Coverage) -> list[str]:
    lo, hi = c.speed_range
    lines = ["### Coverage", "", *_wrap(f"Speed {lo:.2f} to {hi:.2f} m/s; " + _histogram(c.speed, "m/s"))]
    if c.curvature is None or c.curvature_range is None:
        return [*lines, "Curvature: not measured (no yaw rate, or no transition above 0.5 m/s)."]
    lo, hi = c.curvature_range
    text = f"Curvature {lo:.2f} to {hi:.2f} 1/m (yaw rate / speed above 0.5 m/s); "
    return [*lines, *_wrap(text + _histogram(c.curvature, "1/m"))]


def _warnings(report: QualityReport) -> list[str]:
    lines = ["### Warnings", ""]
    if not report.warnings:
        return [*lines, "None."]
    return lines + [line for w in report.warnings for line in _wrap(f"- {w}", "  ")]
