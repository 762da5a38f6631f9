"""What the pace studies share: the pace ladder and the rule of a clean lap.

A *pace* is a pair ``(lateral_accel, max_speed)``: the speed profile's lateral-acceleration
limit (m/s^2) and top speed (m/s); braking and traction scale with the lateral limit
(:meth:`rkmpc.track.speed_profile.SpeedLimits.at_pace`). A *ladder* is an increasing sequence of
paces, climbed one step at a time by :func:`rkmpc.experiments.studies.pace.study_pace` and
:func:`rkmpc.experiments.studies.learn_pace.learn_pace`.

A lap is *clean* (:func:`lap_verdict`) when the run completed every lap it was asked for (so it
never left the track: leaving ends the run), no step found the car inadmissibly far from the
reference (status ``inadmissible``), and at most :data:`MAX_FALLBACK_SHARE` of its steps ended in
a fall-back (any status but ``ok``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from typing import Any

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer
from rkmpc.sim.closed_loop import SimResult

__all__ = [
    "DEFAULT_LADDERS",
    "MAX_FALLBACK_SHARE",
    "MAX_PACES",
    "Pace",
    "car_ladder",
    "check_ladder",
    "data_verdict",
    "lap_verdict",
    "pace_label",
    "pace_ladder",
    "run_verdict",
]

#: A pace: (lateral-acceleration limit in m/s^2, top speed in m/s).
Pace = tuple[float, float]

#: Largest share of a run's steps that may end in a fall-back (any status but ``ok``) for its
#: laps to count as clean: 2 %, about one step in fifty (one second in a 1:10 lap of 25 s).
MAX_FALLBACK_SHARE = 0.02

#: Default ladder per vehicle preset: (first pace, step, number of steps). The first pace is the
#: preset's own (4 m/s^2, 3.5 m/s for the 1:10 car; 5 m/s^2, 25 m/s for the full-size car); the
#: top speed is capped at the car's (8 m/s for the 1:10 car). The ladder goes on beyond the tyres'
#: grip (about 11 m/s^2 for the 1:10 car, 10 for the full-size one), so that every controller,
#: the best one included, stops on it: the f1tenth ladder runs (4, 3.5), (4.5, 4), ..., (8.5, 8),
#: (9, 8), ..., (24, 8) (``nmpc-dynamic``, given the true tyres, stops at 16.5/8 on the built-in
#: track, where the ladder of 20 steps ended at 14/8 under it). A climb ends at its first unclean
#: pace, so the rungs above cost nothing.
DEFAULT_LADDERS: dict[str, tuple[Pace, Pace, int]] = {
    "f1tenth": ((4.0, 3.5), (0.5, 0.5), 40),
    "fullsize": ((5.0, 25.0), (0.5, 2.5), 16),
}
#: Most paces a ladder may hold: a ladder is a list of full laps per pace.
MAX_PACES = 60


def pace_label(pace: Pace) -> str:
    """``"4.5/4.0"``: lateral limit (m/s^2) / top speed (m/s)."""
    return f"{pace[0]:g}/{pace[1]:g}"


def pace_ladder(
    vehicle: str = "f1tenth",
    *,
    start: Pace | None = None,
    step: Pace | None = None,
    steps: int | None = None,
    top_speed: float | None = None,
) -> tuple[Pace, ...]:
    """``start``, then ``steps`` paces each ``step`` above the last; the top speed capped at the car's.

    Each of ``start``, ``step``, ``steps`` left None takes the vehicle's default
    (:data:`DEFAULT_LADDERS`); ``top_speed`` None is the preset car's (``drive.max_speed``). Paces
    that the cap makes equal to the one below are dropped.
    """
    if vehicle not in DEFAULT_LADDERS:
        raise ParameterError(f"pace_ladder: no default ladder for vehicle {vehicle!r}; give the paces")
    d_start, d_step, d_steps = DEFAULT_LADDERS[vehicle]
    a0, v0 = _pace("pace_ladder start", d_start if start is None else start)
    da, dv = d_step if step is None else step
    n = d_steps if steps is None else steps
    if not is_integer(n, 0) or n >= MAX_PACES:
        raise ParameterError(f"pace_ladder: steps must be an integer from 0 to {MAX_PACES - 1}, got {n!r}")
    if not (math.isfinite(da) and math.isfinite(dv) and da >= 0 and dv >= 0 and da + dv > 0):
        raise ParameterError(f"pace_ladder: step must be two non-negative numbers, not both 0, got {step!r}")
    top = load_preset(vehicle).vehicle.drive.max_speed if top_speed is None else top_speed
    if not (math.isfinite(top) and top > 0):
        raise ParameterError(f"pace_ladder: top_speed must be finite and > 0, got {top_speed!r}")
    out: list[Pace] = []
    for i in range(int(n) + 1):
        pace = (round(a0 + i * da, 6), round(min(v0 + i * dv, top), 6))
        if not out or pace != out[-1]:
            out.append(pace)
    return check_ladder("pace_ladder", out)


def car_ladder(
    car: CarConfig,
    *,
    start: Pace | None = None,
    step: Pace | None = None,
    steps: int | None = None,
) -> tuple[Pace, ...]:
    """The ladder of a car (:class:`rkmpc.config.car.CarConfig`).

    As for the presets, the ladder starts at the car's own pace: its limits' ``lateral_accel`` and
    ``max_speed`` (a file's ``[limits]``, else the preset's) unless ``start`` is given, and it is
    capped at the car's top speed (its ``vehicle.drive.max_speed``); ``step`` and ``steps`` default
    to the preset's (:data:`DEFAULT_LADDERS`). For a preset as it is
    (:meth:`CarConfig.from_preset`) this is :func:`pace_ladder` of the preset.
    """
    own = (car.limits.lateral_accel, car.limits.max_speed)
    return pace_ladder(
        car.preset,
        start=own if start is None else start,
        step=step,
        steps=steps,
        top_speed=car.vehicle.drive.max_speed,
    )


def _pace(name: str, value: Any) -> Pace:
    try:
        lateral, speed = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}: a pace is (lateral_accel, max_speed), got {value!r}") from None
    if not (math.isfinite(lateral) and math.isfinite(speed) and lateral > 0 and speed > 0):
        raise ParameterError(f"{name}: a pace needs a positive lateral limit and top speed, got {value!r}")
    return lateral, speed


def check_ladder(name: str, paces: Iterable[Any]) -> tuple[Pace, ...]:
    """``paces`` as a ladder: non-empty, positive, each pace at least as fast as the one below in both."""
    if isinstance(paces, (str, bytes)) or not isinstance(paces, Iterable):
        raise ParameterError(f"{name}: paces must be a sequence of (lateral_accel, max_speed), got {paces!r}")
    out = tuple(_pace(name, p) for p in paces)
    if not out:
        raise ParameterError(f"{name}: the ladder holds no pace")
    if len(out) > MAX_PACES:
        raise ParameterError(f"{name}: {len(out)} paces; a ladder holds at most {MAX_PACES}")
    for low, high in itertools.pairwise(out):
        if high[0] < low[0] or high[1] < low[1] or high == low:
            raise ParameterError(
                f"{name}: each pace must be faster than the one below (neither value lower), "
                f"got {pace_label(low)} then {pace_label(high)}"
            )
    return out


def lap_verdict(
    *,
    completed: bool,
    outcome: str,
    progress: float,
    fallback_count: int,
    steps: int,
    status_counts: Mapping[str, int] | None,
) -> str | None:
    """None for clean laps (see the module), else why not, e.g. ``"off_track at 44%"``.

    ``progress`` is the fraction (0-1) of the laps asked for.
    """
    if not completed:
        return f"{outcome} at {progress:.0%}"
    counts = dict(status_counts or {})
    inadmissible = counts["inadmissible"] if "inadmissible" in counts else 0
    if inadmissible:
        return f"{inadmissible} inadmissible steps"
    share = fallback_count / max(steps, 1)
    if share > MAX_FALLBACK_SHARE:
        return f"fall-backs in {share:.1%} of steps (> {MAX_FALLBACK_SHARE:.0%})"
    return None


def run_verdict(result: SimResult, laps: int) -> str | None:
    """:func:`lap_verdict` of a run asked to drive ``laps`` laps."""
    return lap_verdict(
        completed=result.completed,
        outcome=result.outcome,
        progress=min(result.progress / laps, 1.0),
        fallback_count=result.fallback_count,
        steps=len(result.log),
        status_counts=result.status_counts,
    )


def data_verdict(metadata: Mapping[str, Any]) -> str | None:
    """:func:`lap_verdict` of recorded laps (:func:`rkmpc.sim.collect.collect` metadata)."""
    return lap_verdict(
        completed=bool(metadata["completed"]),
        outcome=str(metadata["outcome"]),
        progress=min(float(metadata["progress_laps"]) / int(metadata["laps"]), 1.0),
        fallback_count=int(metadata["fallback_count"]),
        steps=int(metadata["steps"]),
        status_counts=metadata["status_counts"],
    )
