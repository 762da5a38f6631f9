"""The findings of a data-quality report that need a look, in words (its ``warnings``)."""

from __future__ import annotations

from rkmpc.learning.data.quality.report import QualityReport

__all__ = ["findings"]


def findings(report: QualityReport, dead_columns: tuple[str, ...] = ()) -> tuple[str, ...]:
    """What in ``report`` a user should know before learning from the data.

    Parameters
    ----------
    report : QualityReport
        The report (its own ``warnings`` are not read).
    dead_columns : tuple of str
        Columns the import reads that are constant in every row (``file:column``).
    """
    out = [f"{column} is the same in every row: nothing is measured there" for column in dead_columns]
    for rate in report.rates:
        if rate.gaps:
            start, length = max(rate.gaps, key=lambda gap: gap[1])
            out.append(
                f"{rate.signal} ({rate.source}): {len(rate.gaps)} gap(s) over {rate.gap_s:g} s, "
                f"the longest {length:.2f} s at {start:.2f} s"
            )
    if report.jumps:
        worst = max(report.jumps, key=lambda j: j.distance_m - j.expected_m)
        what = "across them left out" if report.raw else "hold one: outliers to drop or smooth"
        out.append(
            f"{len(report.jumps)} pose jump(s), the largest {worst.distance_m:.2f} m in "
            f"{worst.interval_s:.3f} s at {worst.time_s:.2f} s; {report.jump_transitions} "
            f"transition(s) {what}"
        )
    fit = report.speed_scale
    if fit is not None and fit.warning:
        out.append(
            f"the speed sensor reads {fit.factor:.3f} times the speed of the pose: far from 1 "
            "(a wheel-speed scale, a gear ratio or a unit to check)"
        )
    # A speed that fits no unit is the scale's warning already.
    scaled = fit is not None and fit.warning
    out += [
        u.message
        for u in report.units
        if u.suspicious and not (scaled and u.signal == "speed" and u.match is None)
    ]
    point = report.pose_point
    if point is not None and point.consistent is False:  # a verdict: expected_m is known
        out.append(
            f"the pose moves like a point {point.offset_m:.3f} m ahead of the rear axle, where the "
            f"centre of gravity the data should hold is {point.expected_m:.3f} m ahead: check which "
            "point of the car the pose is of (the spec's pose frame: cog or rear-axle)"
        )
    if report.reversing is not None and report.reversing.segments:
        r = report.reversing
        out.append(f"{r.segments} reversing segment(s), {r.total_s:.2f} s in all: left out")
    if report.stale_command_samples:
        out.append(f"{report.stale_command_samples} grid sample(s) had no fresh command: left out")
    if len(report.episodes) > 1:
        out.append(f"the data fall into {len(report.episodes)} episodes")
    return tuple(out)
