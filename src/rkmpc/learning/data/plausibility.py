"""Data that cannot be right are refused before a model is learned from them.

:class:`~rkmpc.learning.data.dataset.TransitionDataset` checks each value (finite, speeds >= 0, angles
not in degrees by magnitude); the checks here look at the transitions as motion of the car, so that a
model is never learned, and reported with a small held-out error, from data that describe no motion
or a motion no car makes. They run where a model is learned (:func:`rkmpc.learning.pipeline.train_model`,
``rkmpc train``) and raise :class:`~rkmpc.core.errors.InputFileError` naming the data set, the field
and the rows at fault.

Thresholds are relative to the car (its wheelbase ``L``, m) and the control period ``dt`` (s), and
generous: recorded laps, random excitation and bag imports pass by a wide margin.

- The car must travel at least :data:`MIN_TRAVEL_WHEELBASES` wheelbases in all (a car that stood
  still teaches nothing, yet trains to a held-out error of zero).
- A transition is *consistent* when the distance between its two positions is within a factor
  :data:`MOTION_FACTOR` of what the speeds give over ``dt``, with a slack of
  :data:`POSITION_SLACK_WHEELBASES` wheelbases for localisation noise. Shuffled or misaligned next
  observations fail on most rows.
- Where the car moves more than that slack in a period, its heading must point along its motion to
  within :data:`MAX_HEADING_ERROR` rad (side slip stays well below it). A heading in degrees, or
  a heading of another frame, fails on most rows.

More than :data:`MAX_BAD_SHARE` of the rows failing either test refuses the data.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from rkmpc.core.errors import InputFileError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.data.dataset import TransitionDataset

__all__ = [
    "MAX_BAD_SHARE",
    "MAX_HEADING_ERROR",
    "MIN_TRAVEL_WHEELBASES",
    "MOTION_FACTOR",
    "POSITION_SLACK_WHEELBASES",
    "check_learnable",
]

#: Least distance (in wheelbases) the car must travel over the whole data set.
MIN_TRAVEL_WHEELBASES = 5.0
#: A transition's displacement may differ from speed x dt by this factor either way.
MOTION_FACTOR = 3.0
#: Slack (in wheelbases) on each transition's displacement: localisation noise.
POSITION_SLACK_WHEELBASES = 0.1
#: Largest angle (rad) between the heading and the direction of motion (about 46 degrees).
MAX_HEADING_ERROR = 0.8
#: Largest share of the transitions that may fail the motion or heading test.
MAX_BAD_SHARE = 0.1

_X, _Y, _YAW, _SPEED = (OBSERVATION_FIELDS.index(n) for n in ("x", "y", "yaw", "speed"))


def check_learnable(
    data: TransitionDataset, wheelbase: float, source: str, fields: Sequence[str] = ()
) -> None:
    """Refuse data no model should be learned from (see the module's notes).

    Parameters
    ----------
    data : TransitionDataset
        The data set.
    wheelbase : float
        Wheelbase of the car (m): the length the thresholds scale with.
    source : str
        Name of the data set in messages (its file).
    fields : sequence of str
        Observation fields the model reads (others, such as command history, are ignored): each
        must be finite in every row of ``obs`` and ``next_obs``.

    Raises
    ------
    InputFileError
        Naming ``source``, the field and the rows at fault.
    """
    for name in fields:
        if name not in OBSERVATION_FIELDS:
            continue
        col = OBSERVATION_FIELDS.index(name)
        for label, array in (("obs", data.obs), ("next_obs", data.next_obs)):
            bad = ~np.isfinite(array[:, col])
            if np.any(bad):
                raise InputFileError(
                    source,
                    f"{int(bad.sum())} of {len(bad)} rows are NaN or infinite (first at row "
                    f"{int(np.argmax(bad))}); the model reads {name}: measure it, or drop those rows",
                    f"{label}.{name}",
                )
    step = data.next_obs[:, (_X, _Y)] - data.obs[:, (_X, _Y)]
    moved = np.hypot(step[:, 0], step[:, 1])
    travel = float(moved.sum())
    if travel < MIN_TRAVEL_WHEELBASES * wheelbase:
        raise InputFileError(
            source,
            f"the car travels {travel:.3g} m in all {len(data)} transitions, less than "
            f"{MIN_TRAVEL_WHEELBASES:g} wheelbases ({MIN_TRAVEL_WHEELBASES * wheelbase:.3g} m): it stood "
            "still, nothing can be learned from these data",
            "obs.x, obs.y",
        )
    slack = POSITION_SLACK_WHEELBASES * wheelbase
    speeds = np.stack([data.obs[:, _SPEED], data.next_obs[:, _SPEED]])
    fastest, slowest = speeds.max(axis=0) * data.dt, speeds.min(axis=0) * data.dt
    inconsistent = (moved > MOTION_FACTOR * fastest + slack) | (moved < slowest / MOTION_FACTOR - slack)
    _refuse_share(
        source,
        inconsistent,
        "next_obs",
        f"the distance between obs and next_obs is not speed x dt ({data.dt:g} s) within a factor "
        f"{MOTION_FACTOR:g} (+ {slack:.3g} m): are the next observations shuffled or misaligned, or "
        "is dt wrong?",
    )
    going = moved > slack
    direction = np.arctan2(step[:, 1], step[:, 0])
    half_turn = np.angle(np.exp(1j * (data.next_obs[:, _YAW] - data.obs[:, _YAW]))) / 2.0
    heading = data.obs[:, _YAW] + half_turn
    error = np.abs(np.angle(np.exp(1j * (heading - direction))))
    _refuse_share(
        source,
        going & (error > MAX_HEADING_ERROR),
        "obs.yaw",
        f"the heading differs from the direction of motion by more than {MAX_HEADING_ERROR:g} rad "
        f"({math.degrees(MAX_HEADING_ERROR):.0f} deg): is yaw in degrees, or in another frame than x, y?",
        out_of=int(going.sum()),
    )


def _refuse_share(source: str, bad: np.ndarray, field: str, why: str, out_of: int | None = None) -> None:
    """InputFileError when more than :data:`MAX_BAD_SHARE` of ``out_of`` rows (default all) are ``bad``."""
    total = len(bad) if out_of is None else out_of
    count = int(bad.sum())
    if total and count > MAX_BAD_SHARE * total:
        raise InputFileError(
            source,
            f"{count} of {total} transitions ({100 * count / total:.0f} %, more than "
            f"{100 * MAX_BAD_SHARE:.0f} %) fail a consistency check, first at row "
            f"{int(np.argmax(bad))}: {why}",
            field,
        )
